"""A P-GWR whose neurons carry local linear models (beyond the paper), learned online.

Why: the paper's P-GWR predicts the output weights of the regressor's BMU (Eq. 10, VQTAM), so a
prediction can only be one of the prototypes, and prototypes sit ~0.1-0.2 rad apart: a floor on
the error however well the motion is known, and on steady motion worse than holding the pose. The
local-linear-map extension of VQTAM/SOM that the paper cites (Walter et al. 1990; Vesanto 1997)
gives every neuron i, besides its input weights w_i and output weights v_i, a matrix A_i, and
predicts

    y(r) = v_b + A_b^T (r - w_b)        (b = BMU of the regressor r)

so the output varies continuously between prototypes. Here, in addition:

- targets are displacements from the newest observed frame, y = [x(t+k) - x(t)]_{k=1..h} (vector
  output, no recursive roll-out): a fresh neuron predicts "no movement", i.e. hold-last;
- A_b learns by normalised LMS on the residual the neuron's constant output leaves,
  A_b += mu (y - v_b - A_b^T d) d^T / (||d||^2 + delta) with d = r - w_b, taken before the usual GWR
  step (Eqs. 8-9) moves w_b and v_b; a new neuron inherits its parent's A;
- the insertion threshold follows the data instead of a constant a_T: a neuron is inserted when the
  regressor's per-frame RMS distance to its BMU exceeds `insertion_scale` x the running RMS of
  the frame-to-frame motion (never below `noise_floor` rad), so a neuron covers about the same
  stretch of a movement whatever the speed, units or noise of the data.

- consolidation (`consolidate_after` visits): a neuron learns (its position, output weight and
  local model) at full rate for its first visits as BMU, then its rates fall as 1/visits, so that
  it keeps the average over everything it has seen instead of the fit to its most recent visits.
  Why: where movements share the regressor space (above all the onsets from the common rest pose),
  each new movement rewrote the outputs of the neurons it shares with the earlier ones, and the
  earlier ones were forgotten.
- recruitment (`recruit_surprise`, `recruit_after`): a consolidated neuron whose read-out misses a
  pair by far more than it usually misses (squared error > `recruit_surprise` x its running mean)
  does not learn that pair; when that happens `recruit_after` (2) times in a row, a new neuron is
  recruited at the pair itself, predicting it exactly (one odd pair is only ignored). Why: such a pair
  belongs to a movement the neuron has not seen (a new movement through poses an old one shares);
  averaging it into the old neuron (consolidation) keeps neither, a neuron of its own keeps both.
  GWR's own insertion cannot do this: it looks at the regressor alone, and the regressor is close.
  A consolidated neighbour that such a pair surprises is not moved by it either, or the new
  movement's neurons would drag the old movement's away from it.

Everything else (counters, edges, ageing, removal, eviction at `max_neurons`) is the GWR of `gwr.py`;
the matrices and visit counts move with their neurons in the same vectorised steps. A recruit at
`max_neurons` evicts as an insertion does.
`predictor.LocalLinearPredictor` is the online predictor around it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.learning.gwr import Prepared
from gwr_predictor.learning.params import GWRParams
from gwr_predictor.learning.predictive_gwr import PredictiveGWR


class LocalLinearPGWR(PredictiveGWR):
    """P-GWR over [regressor | output] whose neurons each also hold a (in_dim, out_dim) matrix and
    count their visits (learning steps as BMU since insertion).

    `consolidate_after` (visits; 0 = never): past it, all a neuron's rates (its NLMS rate and the
    GWR step's, Eqs. 4 and 9) are scaled by consolidate_after / visits, the search-then-converge
    schedule of stochastic approximation (constant, then 1/t): position and local model become the
    average over all its visits, not the fit to the most recent ones. A new neuron starts at full
    rate.

    `recruit_surprise` (0 = never; only consolidated neurons recruit): a pair surprises a consolidated
    neuron when its read-out's mean squared error on it exceeds recruit_surprise x its running mean
    (`readout_mse`, over its own unsurprised visits as BMU). A surprised BMU is not moved by the pair;
    at the `recruit_after`-th surprising pair in a row (`surprise_streaks`) it leaves the pair to a
    new neuron placed at it (input x, output y, the BMU's matrix, an edge to the BMU). A consolidated
    neighbour (of the block `learn_local` updates) that the pair surprises is not moved by it either.
    """

    #: at least the visits of the most visited neuron (removals do not lower it): 0 = nobody consolidates
    _most_visits: float = 0.0
    #: per visit of a neuron as BMU, the weight of its newest squared read-out error in `readout_mse`
    ERROR_RATE: ClassVar[float] = 0.05
    #: neurons recruited since this network was created (or loaded from a checkpoint that counted them)
    recruited: int = 0
    # per-neuron storage that `_alloc` grows with the GWR's: local models, visits, read-out errors, streaks
    _A: np.ndarray
    _visits: np.ndarray
    _mse: np.ndarray
    _streak: np.ndarray

    def __init__(self, in_dim: int, out_dim: int, params: GWRParams, rng: np.random.Generator, *,
                 init_low: float | np.ndarray = -1.0, init_high: float | np.ndarray = 1.0,
                 distance_factor: float = 1.0, rate: float = 0.5, delta: float = 1e-4,
                 consolidate_after: float = 0.0, recruit_surprise: float = 0.0, recruit_after: int = 1) -> None:
        self.rate, self.delta = float(rate), float(delta)
        self.consolidate_after = float(consolidate_after)
        self.recruit_surprise = float(recruit_surprise)
        self.recruit_after = int(recruit_after)
        super().__init__(in_dim, out_dim, params, rng, init_low=init_low, init_high=init_high,
                         distance_factor=distance_factor)

    # --- the matrices follow their neurons (allocation, insertion, removal) ----------------------
    def _alloc(self, cap: int) -> None:
        n = self._n
        super()._alloc(cap)
        a = np.zeros((cap, self.match_dim, self.dim - self.match_dim))
        visits = np.zeros(cap)
        mse = np.full(cap, np.nan)  # NaN: not yet a BMU
        streak = np.zeros(cap)
        if n and hasattr(self, "_A"):  # growing: the first allocation (from GWR's setup) has nothing to keep
            a[:n] = self._A[:n]
            visits[:n] = self._visits[:n]
            mse[:n] = self._mse[:n]
            streak[:n] = self._streak[:n]
        self._A, self._visits, self._mse, self._streak = a, visits, mse, streak

    def _append(self, xm: np.ndarray, xc: np.ndarray, b: int) -> int:
        r = super()._append(xm, xc, b)
        self._A[r] = self._A[b]
        self._visits[r] = 0.0  # a new neuron learns at full rate, whatever its parent has seen
        self._mse[r] = np.nan
        self._streak[r] = 0.0
        return r

    def _remove(self, i: int) -> int:
        last = self._n - 1
        if i != last:
            self._A[i] = self._A[last]
            self._visits[i] = self._visits[last]
            self._mse[i] = self._mse[last]
            self._streak[i] = self._streak[last]
        self._A[last] = 0.0
        self._visits[last] = 0.0
        self._mse[last] = np.nan
        self._streak[last] = 0.0
        return super()._remove(i)

    # --- insertion follows the data -------------------------------------------------------------
    def follow_motion_scale(self, insertion_distance: float) -> None:
        """Insert a neuron where the BMU is farther than `insertion_distance` (the regressor's units).

        Here the GWR's distance factor is learned state, not a setting: it follows the data's running
        motion scale, so that Eq. 2's test exp(-c d) < a_T holds exactly when d exceeds that distance
        (c = -ln a_T / distance), whatever a_T is."""
        self.distance_factor = -math.log(self.params.activation_threshold) / insertion_distance

    # --- consolidation --------------------------------------------------------------------------
    def _block_plasticity(self, block: np.ndarray) -> np.ndarray | None:
        """Per neuron of `block`: min(1, consolidate_after / visits), the factor on all its rates; None
        while no neuron of the block has consolidated (all at full rate) or consolidation is off."""
        after = self.consolidate_after
        if 0 < after < self._most_visits:
            visits = self._visits[block]
            if visits.max() > after:
                return np.minimum(1.0, after / np.maximum(visits, 1.0))
        return None

    def _step_rates(self, block: np.ndarray, h: np.ndarray, prepared: Prepared | None = None) -> np.ndarray:
        """The GWR step's rates (Eqs. 4, 9) scaled by each neuron's plasticity: a consolidated neuron
        moves, and changes its output weight, as the running mean of its visits. Scaling position and
        output alike leaves its local model's function v + A^T (r - w) where its own visits put it."""
        rate = super()._step_rates(block, h)
        if prepared is not None and prepared.scaled == block.size:  # `learn_local`'s, for this very block
            plasticity = prepared.rate_scale
        else:
            plasticity = self._block_plasticity(block)
        return rate if plasticity is None else rate * plasticity[:, None]

    @property
    def matrices(self) -> np.ndarray:
        """(n, in_dim, out_dim) view of the local linear models."""
        return self._A[:self._n]

    @property
    def visits(self) -> np.ndarray:
        """(n,) view of each neuron's learning steps as BMU since it was inserted."""
        return self._visits[:self._n]

    @property
    def surprise_streaks(self) -> np.ndarray:
        """(n,) view of each neuron's surprising visits in a row as a consolidated BMU (recruitment)."""
        return self._streak[:self._n]

    @property
    def readout_mse(self) -> np.ndarray:
        """(n,) view of each neuron's running mean squared read-out error on the pairs it learned as
        BMU (NaN: none yet), what recruitment compares a new pair's error with."""
        return self._mse[:self._n]

    def _recruit(self, x_in: np.ndarray, y: np.ndarray, b: int, keep: np.ndarray) -> int:
        """A new neuron at the pair (x_in, y) with b's matrix, full plasticity and an edge to b; at
        `max_neurons` the neuron best-matching longest ago outside `keep` (b's block) makes room first
        (none recruited if all are kept). Returns b's index after."""
        self._search.kept = None  # the step's search (`search_keep`) is stale once the network changes
        if self.params.max_neurons is not None and self._n >= self.params.max_neurons:
            victim = self._victim(keep, b)
            if victim < 0:
                return b
            b = victim if self._evict(victim) == b else b
        r = self._append(x_in, y, b)
        self._put(r, np.concatenate([x_in, y]))
        self._edges.link(r, b)
        self._matched[r] = self._matched[b] = self.clock
        self.last_inserted = r
        self.recruited += 1
        return b

    # --- learning and prediction -----------------------------------------------------------------
    #: (rate, neighbour rate) of `_nlms_rates`, the per-row NLMS rates of the longest block [b, neighbours...]
    _nlms_key: tuple[float, float] | None = None
    _nlms_rates: np.ndarray

    def _set_nlms_rates(self, neighbour_rate: float) -> None:
        """[rate, neighbour_rate, ...] for the longest block, kept while the rates stay (not built every step)."""
        rates = np.full(self._block.size, neighbour_rate)
        rates[0] = self.rate
        self._nlms_key, self._nlms_rates = (self.rate, neighbour_rate), rates

    def learn_local(self, x_in: np.ndarray, y: np.ndarray, neighbour_rate: float = 0.0) -> int:
        """One step on a trusted (x_in, y) pair: the BMU's local model by NLMS (and, with
        `neighbour_rate`, its topological neighbours' at that rate, one gathered block; each scaled by
        its plasticity when consolidating), then the GWR step (which reuses this search:
        `search_keep`), then the BMU's visit is counted. Returns the GWR step's BMU index. A
        consolidated BMU surprised by the pair (`recruit_surprise`) learns nothing: a neuron is
        recruited for the pair instead (at the `recruit_after`-th surprise in a row; before it, the BMU
        is not moved), and the BMU's index is returned; a surprised consolidated neighbour is not
        moved by the pair (plasticity 0)."""
        b = int(self.search_keep(x_in).argmax())
        nb, slots = self._edges.neighbours(b)  # `neighbour_slots`, a call less
        if neighbour_rate > 0:
            block = self._block[:nb.size + 1]  # the GWR step's buffer, where it puts this very block too
            block[0] = b
            block[1:] = nb
            if self._nlms_key != (self.rate, neighbour_rate):
                self._set_nlms_rates(neighbour_rate)
            rates = self._nlms_rates[:block.size]
        else:
            block, rates = np.array([b]), np.array([self.rate])
        # `_block_plasticity` is None until some neuron has consolidated: checked here first, a call less
        plasticity = self._block_plasticity(block) if 0 < self.consolidate_after < self._most_visits else None
        # the block's rows gathered once (`take`: cheaper than fancy indexing), handed on to the GWR step
        wa = self._wa.take(block, axis=0)
        d = x_in - wa[:, :self.match_dim]  # (k, in)
        a = self._A.take(block, axis=0)
        d_a = np.matmul(d[:, None, :], a)[:, 0]
        wo = self._wo.take(block, axis=0)
        y_wo = y - wo
        err = y_wo - d_a
        if self.recruit_surprise > 0:
            e2 = np.vecdot(err, err) / err.shape[1]
            bmu_surprised = False
            if plasticity is not None:
                surprised = (plasticity < 1.0) & (e2 > self.recruit_surprise * self._mse[block])  # NaN: False
                bmu_surprised = bool(surprised[0])
                plasticity[surprised] = 0.0  # a surprised consolidated neuron is not moved by the pair
            if bmu_surprised:
                self._streak[b] += 1.0
                if self._streak[b] >= self.recruit_after:
                    self._streak[b] = 0.0
                    self.clock += 1
                    return self._recruit(x_in, y, b, block)
            else:  # a surprising pair is not what the neuron usually misses: only the others count
                self._streak[b] = 0.0
                known, e2_b = self._mse.item(b), e2.item(0)  # Python floats: the same arithmetic, cheaper
                self._mse[b] = e2_b if math.isnan(known) else known + self.ERROR_RATE * (e2_b - known)
        if plasticity is not None:
            rates = rates * plasticity
        dd = np.vecdot(d, d)
        gain = rates / (dd + self.delta)
        a += np.einsum("ki,ko->kio", gain[:, None] * d, err)  # rank-1 NLMS step per neuron
        self._A[block] = a
        b = self.learn_unchecked(x_in, y, neighbours=Prepared(b, nb, slots, float(dd[0]), plasticity, block.size,
                                                              (wa, d, wo, y_wo)))
        visits = self._visits.item(b) + 1.0
        self._visits[b] = visits
        self._most_visits = max(self._most_visits, visits)
        return b

    def predict_local(self, x_in: np.ndarray, k: int = 1) -> np.ndarray:
        """v_b + A_b^T (x - w_b) for the BMU b of a trusted regressor (a new array); with k > 1 the
        local models of the k nearest neurons, averaged with weights 1 / distance."""
        if k == 1 or self._n < 2:
            b = self.match_unchecked(x_in)
            return self._wo[b] + (x_in - self._w[b]) @ self._A[b]
        n = self._n
        k = min(k, n)
        idx = self._search.affinity(x_in, n).argpartition(n - k)[n - k:]
        # gathered by `take` (cheaper than fancy indexing); ys = v + A^T d, as one sum per row
        d = x_in - self._wa.take(idx, axis=0)[:, :self.match_dim]  # (k, in)
        ys = self._wo.take(idx, axis=0)
        ys += np.matmul(d[:, None, :], self._A.take(idx, axis=0))[:, 0]
        dist = np.sqrt(np.vecdot(d, d))
        distances = dist.tolist()  # k floats: their min and its first index cost less in Python
        self.last_distance = nearest = min(distances)
        if nearest <= 1e-12:
            return ys[distances.index(nearest)]
        wts = 1.0 / dist
        wts /= np.add.reduce(wts)  # `wts.sum()` without its Python wrapper
        return wts @ ys

    # --- persistence -------------------------------------------------------------------------------
    def _capture(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """The network as a checkpoint member: its settings come from its owner's parameters."""
        arrays = {"weights": self.weights.copy(), "matrices": self.matrices.copy(), "visits": self.visits.copy(),
                  "readout_mse": self.readout_mse.copy(), "surprise_streaks": self.surprise_streaks.copy(),
                  "counters": self.counters.copy(), "edges": self.edge_array(),
                  "last_matched": self.last_matched.copy()}
        return {"distance_factor": self.distance_factor, "recruited": self.recruited, "clock": self.clock,
                "evicted": self.evicted}, arrays

    def _restored(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray],
                  where: str = "") -> LocalLinearPGWR:
        """The saved network with this (fresh) one's settings; DefaultPredictorError if it does not fit."""
        net = self.from_parts(
            arrays["weights"], arrays["matrices"], self.params, edges=arrays["edges"], counters=arrays["counters"],
            match_dim=self.match_dim, distance_factor=float(header["distance_factor"]), rate=self.rate,
            delta=self.delta, visits=arrays["visits"], consolidate_after=self.consolidate_after,
            readout_mse=arrays["readout_mse"], recruit_surprise=self.recruit_surprise,
            recruited=int(header["recruited"]), streaks=arrays["surprise_streaks"], recruit_after=self.recruit_after)
        net._restore_clock(arrays["last_matched"], int(header["clock"]))
        net.evicted = int(header["evicted"])
        if net.out_dim != self.out_dim:
            raise DefaultPredictorError(f"outputs are {net.out_dim}-d, the parameters say {self.out_dim}")
        return net

    @classmethod
    def from_parts(cls, weights: np.ndarray, matrices: np.ndarray, params: GWRParams, *, edges: Any,
                   counters: np.ndarray, match_dim: int, distance_factor: float, rate: float,
                   delta: float, visits: np.ndarray | None = None, consolidate_after: float = 0.0,
                   readout_mse: np.ndarray | None = None, recruit_surprise: float = 0.0,
                   recruited: int = 0, streaks: np.ndarray | None = None, recruit_after: int = 1) -> LocalLinearPGWR:
        """A network from saved arrays (checkpoints); `visits` None = zeros (needed only when
        consolidating), `readout_mse` None = NaN (needed only when recruiting)."""
        net = cls.from_arrays(weights, params, edges=edges, counters=counters, match_dim=match_dim,
                              distance_factor=distance_factor)
        expected = (net.n_neurons, net.in_dim, net.out_dim)
        if np.shape(matrices) != expected:
            raise DefaultPredictorError(f"local models have shape {np.shape(matrices)}, expected {expected}")
        if not np.isfinite(matrices).all():
            raise DefaultPredictorError("local models contain NaN or infinite values")
        net._A[:net.n_neurons] = matrices
        if visits is not None:
            net._visits[:net.n_neurons] = _per_neuron(visits, net.n_neurons, "visit counts")
            net._most_visits = float(np.max(visits, initial=0.0))
        elif consolidate_after > 0:
            raise DefaultPredictorError("consolidating needs the neurons' visit counts")
        if readout_mse is not None:
            net._mse[:net.n_neurons] = _per_neuron(readout_mse, net.n_neurons, "read-out errors", nan="no visit yet")
        elif recruit_surprise > 0:
            raise DefaultPredictorError("recruiting needs the neurons' read-out errors")
        if streaks is not None:
            net._streak[:net.n_neurons] = _per_neuron(streaks, net.n_neurons, "surprise streaks")
        net.rate, net.delta = float(rate), float(delta)
        net.consolidate_after = float(consolidate_after)
        net.recruit_surprise = float(recruit_surprise)
        net.recruit_after = int(recruit_after)
        net.recruited = int(recruited)
        return net


def _per_neuron(values: Any, n: int, what: str, nan: str | None = None) -> np.ndarray:
    """`values` as n per-neuron figures, finite and >= 0 (or NaN, meaning `nan`, when that is given);
    DefaultPredictorError naming `what` otherwise."""
    if np.shape(values) != (n,):
        raise DefaultPredictorError(f"{what} have shape {np.shape(values)}, expected ({n},)")
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v) & (v >= 0)
    if nan is not None:
        ok |= np.isnan(v)
    if not ok.all():
        raise DefaultPredictorError(f"{what} must be {f'NaN ({nan}) or ' if nan else ''}finite and >= 0")
    return v


