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


class Renders:
    """A PettingZoo environment's ``render``: the environment provides ``render_mode`` (or None)
    and ``_draw(figure)``, which draws its state now; the canvas is made at the first call."""

    render_mode: str | None
    _canvas: Canvas | None = None

    def _draw(self, figure) -> None:
        raise NotImplementedError

    def render(self) -> np.ndarray | None:
        """The picture of the state now (``"rgb_array"``), or it shown in a window (``"human"``)."""
        if self.render_mode is None:
            import gymnasium

            gymnasium.logger.warn("render() without a render_mode: give one to the constructor")
            return None
        if self._canvas is None:
            self._canvas = Canvas(self.render_mode)
        self._draw(self._canvas.figure)
        return self._canvas.show()

