"""Predictive GWR (Sec. III-D): a GWR whose neurons carry input and output weights (VQTAM-style).

BMUs are chosen on the regressor x_in only (Eq. 8); both weight parts move (Eq. 9); a new
neuron sits at 0.5 (x_in + w_in_b), 0.5 (x_out + w_out_b); the prediction is the output weight of
the regressor's BMU (Eq. 10). This is the `GWR` step with the output part carried along.
"""

from __future__ import annotations

from typing import Any, TypeVar

import numpy as np

from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.gwr import GWR
from gwr_predictor.learning.params import GWRParams

_P = TypeVar("_P", bound="PredictiveGWR")


class PredictiveGWR(GWR):
    """GWR over [x_in | x_out] that matches on x_in only."""

    def __init__(self, in_dim: int, out_dim: int, params: GWRParams, rng: np.random.Generator, *,
                 init_low: float | np.ndarray = -1.0, init_high: float | np.ndarray = 1.0,
                 distance_factor: float = 1.0) -> None:
        if out_dim < 1:
            raise LearningError(f"PredictiveGWR out_dim must be >= 1, got {out_dim}")
        super().__init__(in_dim + out_dim, params, rng, match_dim=in_dim, init_low=init_low,
                         init_high=init_high, distance_factor=distance_factor)

    @classmethod
    def from_arrays(cls: type[_P], weights: np.ndarray, params: GWRParams, *, edges: Any = (),
                    counters: np.ndarray | None = None, match_dim: int | None = None,
                    distance_factor: float = 1.0) -> _P:
        """As `GWR.from_arrays` with rows [w_in | w_out]; `match_dim` is the regressor size."""
        if match_dim is None:
            raise LearningError("PredictiveGWR.from_arrays needs match_dim (the regressor size)")
        net = super().from_arrays(weights, params, edges=edges, counters=counters, match_dim=match_dim,
                                  distance_factor=distance_factor)
        if net.match_dim == net.dim:
            raise LearningError("PredictiveGWR needs at least one output value (match_dim < dim)")
        return net

    @property
    def in_dim(self) -> int:
        return self.match_dim

    @property
    def out_dim(self) -> int:
        return self.dim - self.match_dim

    @property
    def weights_in(self) -> np.ndarray:
        """(n, in_dim) view of the input (regressor) weights."""
        return self._w[:self._n]

    @property
    def weights_out(self) -> np.ndarray:
        """(n, out_dim) view of the output weights."""
        return self._wo[:self._n]

    def learn(self, x_in: np.ndarray, x_out: np.ndarray | None = None) -> int:
        """One step on (x_in, x_out) (Eqs. 8-9); returns the BMU index. Also accepts one whole
        [x_in | x_out] vector."""
        if x_out is None:
            return super().learn(x_in)
        return self.learn_unchecked(self._check_input(x_in, self.match_dim), self._check_input(x_out, self.out_dim))

    def predict(self, x_in: np.ndarray) -> np.ndarray:
        """Eq. 10: a copy of the output weights of the BMU of x_in."""
        x_in = self._check_input(x_in, self.match_dim)
        return self._wo[self.nearest(x_in)].copy()

    def output_row(self, i: int) -> np.ndarray:
        """View of neuron i's output weights (valid until the network changes)."""
        return self._wo[i]

    def blended_output(self, xm: np.ndarray, k: int, record: bool = False,
                       affinity: np.ndarray | None = None) -> np.ndarray:
        """Soft read-out (beyond the paper): the output weights of the k nearest neurons of the trusted
        regressor xm, averaged with weights 1/distance (a neuron at distance 0 takes all). k = 1 is
        Eq. 10 (a view of the BMU's output row). With `record`, `last_distance` is the BMU's distance.
        `affinity`: xm's affinity if already computed (e.g. by `search_keep`)."""
        aff = self._search.affinity(xm, self._n) if affinity is None else affinity
        k = min(k, self._n)
        if k == 1:
            b = int(aff.argmax())
            if record:
                self.last_distance = self._distance(b, xm)
            return self._wo[b]
        idx = np.argpartition(aff, self._n - k)[self._n - k:]
        diff = self._w[idx] - xm
        dist = np.sqrt(np.vecdot(diff, diff))
        if record:
            self.last_distance = float(dist.min())
        if dist.min() <= 1e-12:
            return self._wo[idx[int(dist.argmin())]]
        wts = 1.0 / dist
        wts /= wts.sum()
        return wts @ self._wo[idx]


__all__ = ["PredictiveGWR"]
