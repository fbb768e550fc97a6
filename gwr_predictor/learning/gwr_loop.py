"""Reference GWR written as plain per-neuron Python loops: the yardstick of `gwr-predictor bench`.

It performs exactly the step documented in `gwr_predictor.learning.gwr` (same order, same floating-point
expressions, same swap-with-last removal), one neuron at a time, with weights as a list of
vectors and edges as one {neighbour: age} dict per neuron. Tests check that both agree step for
step, which also validates the reference used for the speed ratio. Not for production use.
"""

from __future__ import annotations

import math

import numpy as np

from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.gwr import GWR, counter_decay
from gwr_predictor.learning.params import GWRParams


class LoopGWR:
    """Per-neuron loop GWR with the same semantics as `GWR` (no output part, no size doubling)."""

    def __init__(self, dim: int, params: GWRParams, rng: np.random.Generator, *,
                 init_low: float | np.ndarray = -1.0, init_high: float | np.ndarray = 1.0,
                 distance_factor: float = 1.0) -> None:
        init = rng.uniform(init_low, init_high, size=(2, dim))
        self.params = params
        self.distance_factor = float(distance_factor)
        self.w: list[np.ndarray] = [init[0].copy(), init[1].copy()]
        self.h: list[float] = [1.0, 1.0]
        self.nbrs: list[dict[int, int]] = [{}, {}]

    @classmethod
    def from_gwr(cls, net: GWR) -> LoopGWR:
        """A loop copy of a vectorised network (same neurons, counters, edges)."""
        if net.match_dim != net.dim:
            raise LearningError("LoopGWR mirrors plain GWRs only (no carried output part)")
        loop = cls.__new__(cls)
        loop.params = net.params
        loop.distance_factor = net.distance_factor
        loop.w = [row.copy() for row in net.weights]
        loop.h = [float(v) for v in net.counters]
        loop.nbrs = [{} for _ in range(net.n_neurons)]
        for i, j, a in net.edge_array().tolist():
            loop.nbrs[i][j] = a
            loop.nbrs[j][i] = a
        return loop

    @property
    def n_neurons(self) -> int:
        return len(self.w)

    @property
    def weights(self) -> np.ndarray:
        return np.array(self.w)

    def learn(self, x: np.ndarray) -> int:
        """One GWR step; returns the BMU index."""
        p = self.params
        x = np.asarray(x, dtype=float)
        best, second, b, s = math.inf, math.inf, -1, -1
        for i, w in enumerate(self.w):
            diff = x - w
            d2 = float(np.dot(diff, diff))
            if d2 < best:
                best, second, b, s = d2, best, i, b
            elif d2 < second:
                second, s = d2, i
        dist = math.sqrt(best)
        neighbours = sorted(self.nbrs[b])
        hb = self.h[b]
        insert = (math.exp(-self.distance_factor * dist) < p.activation_threshold
                  and hb < p.firing_threshold
                  and (p.max_neurons is None or len(self.w) < p.max_neurons))
        if not insert:
            self.w[b] = self.w[b] + (p.eps_b * hb) * (x - self.w[b])
            for j in neighbours:
                self.w[j] = self.w[j] + (p.eps_n * self.h[j]) * (x - self.w[j])
        for j in neighbours:
            self.nbrs[b][j] += 1
            self.nbrs[j][b] += 1
            self.h[j] = self._decayed(self.h[j], *counter_decay(p.rho_n, p.kappa))
        self.h[b] = self._decayed(hb, *counter_decay(p.rho_b, p.kappa))
        if insert:
            r = len(self.w)
            self.w.append(0.5 * (x + self.w[b]))
            self.h.append(1.0)
            self.nbrs.append({})
            self._unlink(b, s)
            self._link(r, b)
            self._link(r, s)
        else:
            self._link(b, s)
        old = [j for j in neighbours if j != s and self.nbrs[b][j] > p.max_edge_age]
        for j in old:
            self._unlink(b, j)
        for i in sorted(old, reverse=True):
            if not self.nbrs[i]:
                moved = self._remove(i)
                b = i if b == moved else b
        return b

    @staticmethod
    def _decayed(h: float, a: float, c: float) -> float:
        return min(max(h * a + c, 0.0), 1.0)

    def _link(self, i: int, j: int) -> None:
        self.nbrs[i][j] = 0
        self.nbrs[j][i] = 0

    def _unlink(self, i: int, j: int) -> None:
        self.nbrs[i].pop(j, None)
        self.nbrs[j].pop(i, None)

    def _remove(self, i: int) -> int:
        last = len(self.w) - 1
        if i != last:
            self.w[i], self.h[i], self.nbrs[i] = self.w[last], self.h[last], self.nbrs[last]
            for j, a in self.nbrs[i].items():
                del self.nbrs[j][last]
                self.nbrs[j][i] = a
        self.w.pop()
        self.h.pop()
        self.nbrs.pop()
        return last
