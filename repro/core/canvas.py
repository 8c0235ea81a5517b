"""A matplotlib figure that an environment draws its state on, for PettingZoo's render modes."""

from __future__ import annotations

import numpy as np

RENDER_MODES = ("human", "rgb_array")
"""What the environments' ``render_mode`` may be (or None: no pictures)."""
FIGSIZE, DPI = (9.0, 4.5), 80
"""Size of a picture (inches) and its resolution: 720 x 360 pixels."""


class Canvas:
    """An off-screen figure (``"rgb_array"``: ``show`` returns the picture as an (H, W, 3) uint8
    array; no screen needed) or a window (``"human"``: ``show`` draws it there, where the
    matplotlib backend has windows, and returns None)."""

    def __init__(self, mode: str):
        self.mode = mode
        if mode == "human":
            import matplotlib.pyplot as plt

            self.figure = plt.figure(figsize=FIGSIZE, dpi=DPI)
        else:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure

            self.figure = Figure(figsize=FIGSIZE, dpi=DPI)
            FigureCanvasAgg(self.figure)

    def show(self) -> np.ndarray | None:
        if self.mode == "human":
            import matplotlib
            import matplotlib.pyplot as plt

            if matplotlib.get_backend().lower() != "agg":  # Agg has no window to show
                plt.pause(0.001)
            return None
        self.figure.canvas.draw()
        return np.asarray(self.figure.canvas.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        if self.mode == "human":
            import matplotlib.pyplot as plt

            plt.close(self.figure)
