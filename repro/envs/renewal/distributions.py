"""The event-time distributions of the race-condition study (the paper's Table "nvdt") and of the
renewal processes that measure compute scaling."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import special


@dataclass(frozen=True)
class Distribution:
    """An event-time distribution. All three of the paper's are gamma laws, which gives fast exact
    CDFs (regularized incomplete gamma functions) for the sampling-free computation."""

    name: str
    parameters: str
    shape: float
    scale: float

    def sample(self, rng: np.random.Generator, size: tuple[int, int]) -> np.ndarray:
        return rng.gamma(self.shape, self.scale, size=size)

    def cdf_sf(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = t / self.scale
        return special.gammainc(self.shape, x), special.gammaincc(self.shape, x)

    @property
    def mean(self) -> float:
        return self.shape * self.scale

    def isf(self, q: float) -> float:
        return float(special.gammainccinv(self.shape, q) * self.scale)


DISTRIBUTIONS = {
    "exponential": Distribution("Exponential", "lambda=1", shape=1.0, scale=1.0),
    "chi2": Distribution("Chi-Squared", "k=5", shape=2.5, scale=2.0),
    "gamma": Distribution("Gamma", "k=5, theta=1", shape=5.0, scale=1.0),
}
