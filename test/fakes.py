"""Test doubles and signals shared by several test files."""

import errno

import numpy as np


def damped_oscillation(n: int, seed: int, damping: float, stiffness: float, noise: float) -> np.ndarray:
    """(n, 8) lightly damped oscillations of every joint about 0, driven by a little noise: a linear
    second-order system, so the future displacements are a linear function of the pose and its last change."""
    rng = np.random.default_rng(seed)
    x = np.zeros((n, 8))
    x[0] = x[1] = rng.uniform(-1, 1, 8)
    for t in range(2, n):
        x[t] = x[t - 1] + damping * (x[t - 1] - x[t - 2]) - stiffness * x[t - 1] + rng.normal(scale=noise, size=8)
    return x


class FullDisk:
    """A file whose writes fail like a full disk; everything else goes to the real file."""

    def __init__(self, real) -> None:
        self.real = real

    def write(self, _data) -> int:
        raise OSError(errno.ENOSPC, "No space left on device")

    def __getattr__(self, name):
        return getattr(self.real, name)
