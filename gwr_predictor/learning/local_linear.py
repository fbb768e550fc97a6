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

Everything else (counters, edges, ageing, removal, unbounded growth) is the GWR of `gwr.py`; the
matrices and visit counts move with their neurons in the same vectorised steps.
`LocalLinearPredictor` is the online predictor around it (`step` / `reset_sequence` / checkpoints
like the other predictors).

A global read-out beside the local ones (`global_order` > 0, the default): where a person has shown
little, most neurons have seen a handful of pairs and their local models are noise, while one linear
map fitted exactly to every pair (recursive least squares, `learning/rls.py`, on the newest pose and
its latest changes) already predicts well. Per horizon step the predictor mixes the two read-outs,

    y(r) = w_local,k y_local(r) + w_global,k y_global(r)

with the weights the least-squares fit of the observed displacements on what each read-out predicted
for them (decayed, ridge towards 0 = hold-last), scored when a learned pair's targets are complete:
on motion the network knows, the weights go to the local read-out; on a few minutes of a new person,
the global one carries the prediction until the network has learned the movements.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections import deque
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.learning.checkpoint import CheckpointError, read_checkpoint, require_arrays, write_checkpoint
from gwr_predictor.learning.gwr import InputError
from gwr_predictor.learning.hierarchy import ErrorTracker
from gwr_predictor.learning.params import DEFAULT_HORIZON, MAX_HORIZON, GWRParams
from gwr_predictor.learning.predictive_gwr import PredictiveGWR
from gwr_predictor.learning.rls import RecursiveLeastSquares, window_features
from gwr_predictor.learning.scaling import InputScaling
from gwr_predictor.parameter_spec import ParamSpec, check_fields


class LocalLinearError(GwrPredictorError, ValueError):
    """Invalid local-linear P-GWR parameters or state."""


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

    #: what `learn_local` hands to the GWR step on the same block: (block size, the neurons' plasticity)
    _handed: tuple[int, np.ndarray | None] | None = None
    #: at least the visits of the most visited neuron (removals do not lower it): 0 = nobody consolidates
    _most_visits: float = 0.0
    #: per visit of a neuron as BMU, the weight of its newest squared read-out error in `readout_mse`
    ERROR_RATE: ClassVar[float] = 0.05
    #: neurons recruited since this network was created (or loaded from a checkpoint that counted them)
    recruited: int = 0

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
        old, old_visits, old_mse, old_streak = (getattr(self, k, None) for k in ("_A", "_visits", "_mse", "_streak"))
        n = self._n
        super()._alloc(cap)
        a = np.zeros((cap, self.match_dim, self.dim - self.match_dim))
        visits = np.zeros(cap)
        mse = np.full(cap, np.nan)  # NaN: not yet a BMU
        streak = np.zeros(cap)
        if old is not None and n:
            a[:n] = old[:n]
            visits[:n] = old_visits[:n]
            mse[:n] = old_mse[:n]
            streak[:n] = old_streak[:n]
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

    def _step_rates(self, block: np.ndarray, h: np.ndarray) -> np.ndarray:
        """The GWR step's rates (Eqs. 4, 9) scaled by each neuron's plasticity: a consolidated neuron
        moves, and changes its output weight, as the running mean of its visits. Scaling position and
        output alike leaves its local model's function v + A^T (r - w) where its own visits put it."""
        rate = super()._step_rates(block, h)
        handed, self._handed = self._handed, None
        if handed is not None and handed[0] == block.size:  # from `learn_local` on this very block
            plasticity = handed[1]
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

    def _recruit(self, x_in: np.ndarray, y: np.ndarray, b: int) -> int:
        """A new neuron at the pair (x_in, y) with b's matrix, full plasticity and an edge to b."""
        self._search.kept = None  # the step's search (`search_keep`) is stale once the network changes
        r = self._append(x_in, y, b)
        self._put(r, np.concatenate([x_in, y]))
        self._age[r, b] = self._age[b, r] = 0
        self.last_inserted = r
        self.recruited += 1
        return r

    # --- learning and prediction -----------------------------------------------------------------
    def learn_local(self, x_in: np.ndarray, y: np.ndarray, neighbour_rate: float = 0.0) -> int:
        """One step on a trusted (x_in, y) pair: the BMU's local model by NLMS (and, with
        `neighbour_rate`, its topological neighbours' at that rate, one gathered block; each scaled by
        its plasticity when consolidating), then the GWR step (which reuses this search:
        `search_keep`), then the BMU's visit is counted. Returns the GWR step's BMU index. A
        consolidated BMU surprised by the pair (`recruit_surprise`) learns nothing: a neuron is
        recruited for the pair instead (at the `recruit_after`-th surprise in a row; before it, the BMU
        is not moved), and the BMU's index is returned; a surprised consolidated neighbour is not
        moved by the pair (plasticity 0)."""
        aff = self.search_keep(x_in)
        b = int(aff.argmax())
        nb = (self._age[b, :self._n] >= 0).nonzero()[0]
        if neighbour_rate > 0:
            block = np.empty(nb.size + 1, dtype=nb.dtype)
            block[0] = b
            block[1:] = nb
            rates = np.full(block.size, neighbour_rate)
            rates[0] = self.rate
        else:
            block, rates = np.array([b]), np.array([self.rate])
        plasticity = self._block_plasticity(block)
        d = x_in - self._w[block]  # (k, in)
        a = self._A[block]
        d_a = np.matmul(d[:, None, :], a)[:, 0]
        err = y - self._wo[block] - d_a
        if self.recruit_surprise > 0:
            e2 = np.vecdot(err, err) / err.shape[1]
            bmu_surprised = False
            if plasticity is not None:
                surprised = (plasticity < 1.0) & (e2 > self.recruit_surprise * self._mse[block])  # NaN: False
                # the BMU only while there is room to recruit (at max_neurons it learns the pair as usual)
                surprised[0] &= self.params.max_neurons is None or self._n < self.params.max_neurons
                bmu_surprised = bool(surprised[0])
                plasticity[surprised] = 0.0  # a surprised consolidated neuron is not moved by the pair
            if bmu_surprised:
                self._streak[b] += 1.0
                if self._streak[b] >= self.recruit_after:
                    self._streak[b] = 0.0
                    self._recruit(x_in, y, b)
                    return b
            else:  # a surprising pair is not what the neuron usually misses: only the others count
                self._streak[b] = 0.0
                known = self._mse[b]
                self._mse[b] = e2[0] if math.isnan(known) else known + self.ERROR_RATE * (e2[0] - known)
        if plasticity is not None:
            rates = rates * plasticity
        self._handed = (block.size, plasticity)
        dd = np.vecdot(d, d)
        gain = rates / (dd + self.delta)
        a += np.einsum("ki,ko->kio", gain[:, None] * d, err)  # rank-1 NLMS step per neuron
        self._A[block] = a
        b = self.learn_unchecked(x_in, y, neighbours=(b, nb, float(dd[0])))
        self._handed = None  # unused if the step inserted a neuron instead
        self._visits[b] += 1.0
        self._most_visits = max(self._most_visits, float(self._visits[b]))
        return b

    def predict_local(self, x_in: np.ndarray, k: int = 1) -> np.ndarray:
        """v_b + A_b^T (x - w_b) for the BMU b of a trusted regressor (a new array); with k > 1 the
        local models of the k nearest neurons, averaged with weights 1 / distance."""
        if k == 1 or self._n < 2:
            b = self.match_unchecked(x_in)
            return self._wo[b] + (x_in - self._w[b]) @ self._A[b]
        aff = self._search.affinity(x_in, self._n)
        k = min(k, self._n)
        idx = np.argpartition(aff, self._n - k)[self._n - k:]
        d = x_in - self._w[idx]  # (k, in)
        ys = self._wo[idx] + np.matmul(d[:, None, :], self._A[idx])[:, 0]
        dist = np.sqrt(np.vecdot(d, d))
        self.last_distance = nearest = float(dist.min())
        if nearest <= 1e-12:
            return ys[int(dist.argmin())]
        wts = 1.0 / dist
        return (wts / wts.sum()) @ ys

    # --- persistence -------------------------------------------------------------------------------
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
            raise ValueError(f"local models have shape {np.shape(matrices)}, expected {expected}")
        if not np.isfinite(matrices).all():
            raise ValueError("local models contain NaN or infinite values")
        net._A[:net.n_neurons] = matrices
        if visits is not None:
            net._visits[:net.n_neurons] = _per_neuron(visits, net.n_neurons, "visit counts")
            net._most_visits = float(np.max(visits, initial=0.0))
        elif consolidate_after > 0:
            raise ValueError("consolidating needs the neurons' visit counts")
        if readout_mse is not None:
            net._mse[:net.n_neurons] = _per_neuron(readout_mse, net.n_neurons, "read-out errors", nan="no visit yet")
        elif recruit_surprise > 0:
            raise ValueError("recruiting needs the neurons' read-out errors")
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
    ValueError naming `what` otherwise."""
    if np.shape(values) != (n,):
        raise ValueError(f"{what} have shape {np.shape(values)}, expected ({n},)")
    v = np.asarray(values, dtype=float)
    ok = np.isfinite(v) & (v >= 0)
    if nan is not None:
        ok |= np.isnan(v)
    if not ok.all():
        raise ValueError(f"{what} must be {f'NaN ({nan}) or ' if nan else ''}finite and >= 0")
    return v


def _default_gwr() -> GWRParams:
    return GWRParams(max_edge_age=100)


_LOCAL_LINEAR_SPECS = {spec.name: spec for spec in (
    ParamSpec("order", 4, "frames in the regressor", 1, 32),
    ParamSpec("horizon", DEFAULT_HORIZON, "frames predicted", 1, MAX_HORIZON),
    ParamSpec("n_joints", 8, "joints per frame", 1),
    ParamSpec("insertion_scale", 1.5, "insertion distance in units of the motion scale", 0.0, 1e3,
              lo_open=True, hi_open=True),
    ParamSpec("noise_floor", 0.01, "lower bound of the motion scale (rad)", 0.0, 10.0, lo_open=True, hi_open=True),
    ParamSpec("motion_decay", 0.999, "forgetting of the motion estimate per frame", 0.0, 1.0,
              lo_open=True, hi_open=True),
    ParamSpec("rate", 0.1, "NLMS rate of the local models", 0.0, 1.5),
    ParamSpec("readout_k", 3, "neurons blended in the read-out", 1, 64),
    ParamSpec("neighbour_rate", 0.05, "NLMS rate of the BMU's neighbours", 0.0, 1.5),
    ParamSpec("global_order", 2, "frames the global linear read-out's features span (0: local read-outs only)", 0, 32),
    ParamSpec("global_delta", 100.0, "prior variance of the global read-out's weights (RLS P(0) = delta I)", 0.0,
              lo_open=True),
    ParamSpec("mix_decay", 0.995, "forgetting of the read-outs' mixing statistics per learned pair", 0.0, 1.0,
              lo_open=True),
    ParamSpec("mix_ridge", 0.01, "rad^2 per joint added to the mixing equations (pulls towards hold-last)", 0.0,
              lo_open=True),
    ParamSpec("consolidate_after", 200, "visits after which a neuron's rates fall as 1/visits (0 = never)",
              0, 10**9),
    ParamSpec("recruit_surprise", 9.0, "squared read-out error, in units of a consolidated BMU's running mean, "
              "beyond which a pair surprises it (0 = never recruit)", 0.0, 1e6),
    ParamSpec("recruit_after", 2, "surprising pairs in a row after which a consolidated BMU recruits a neuron",
              1, 1000),
)}
# per setting added after the first local-linear P-GWR, in order: what a checkpoint written before it ran with
_BEFORE = (
    ("global_order", {"global_order": 0}),  # local read-outs only
    ("consolidate_after", {"consolidate_after": 0}),  # constant output rates
    ("recruit_surprise", {"recruit_surprise": 0.0}),  # no recruitment
)


@dataclass(frozen=True)
class LocalLinearParams:
    """Settings of `LocalLinearPredictor` (chosen by `gwr-predictor experiment tune`, see docs).

    `order`: frames in the regressor (newest first). `horizon`: frames predicted. `insertion_scale`:
    insert when the per-frame RMS distance to the BMU exceeds this x the running RMS frame-to-frame
    motion. `noise_floor` (rad): lower bound of that motion scale (tracker jitter). `motion_decay`:
    forgetting factor of the motion estimate per frame. `rate`: NLMS rate mu of the local models
    (0 = plain VQTAM read-out, the ablation). `global_order`: frames the global linear read-out's
    features span (0: none, the predictor before it existed); `global_delta`: the prior variance of its
    weights (large: a weak prior, so it follows the data within a few dozen pairs; the mix below and
    the gate keep an immature fit from doing harm); `mix_decay`, `mix_ridge`: forgetting and ridge of
    the per-step least-squares mix of the local and global read-outs. `consolidate_after`: visits (as BMU) after which a
    neuron's rates fall as consolidate_after / visits (0 = constant rates): without it each
    new movement rewrote the outputs of the neurons it shares with earlier ones (`experiment
    incremental`). 200 is about the memory of Eq. 9's output step at the firing counter's floor,
    1 / (eps_b (1 - 1/kappa)) = 210 visits: a neuron consolidates once it has had that many, and
    from then on its position and output weight are about the running means of its visits.
    `recruit_surprise`: a pair surprises a consolidated BMU when its read-out's squared error exceeds
    this x the neuron's running mean (0 = never recruit; only consolidated neurons recruit, so none
    without `consolidate_after`). `recruit_after`: at that many surprising pairs in a row, the BMU
    leaves the pair to a new neuron placed at it; the surprising pairs before it move nothing and do
    not count in its error. So a new movement through the poses of an old one gets neurons of its own
    instead of being averaged into the old one's (`experiment incremental`), while one odd pair (a
    tracking glitch, one person's quirk) is only ignored.
    `gwr`: the GWR step's parameters (its a_T only fixes the constant -ln a_T the scaled distance is
    compared with).
    """

    order: int = _LOCAL_LINEAR_SPECS["order"].default
    horizon: int = _LOCAL_LINEAR_SPECS["horizon"].default
    n_joints: int = _LOCAL_LINEAR_SPECS["n_joints"].default
    insertion_scale: float = _LOCAL_LINEAR_SPECS["insertion_scale"].default
    noise_floor: float = _LOCAL_LINEAR_SPECS["noise_floor"].default
    motion_decay: float = _LOCAL_LINEAR_SPECS["motion_decay"].default
    rate: float = _LOCAL_LINEAR_SPECS["rate"].default
    readout_k: int = _LOCAL_LINEAR_SPECS["readout_k"].default
    neighbour_rate: float = _LOCAL_LINEAR_SPECS["neighbour_rate"].default
    global_order: int = _LOCAL_LINEAR_SPECS["global_order"].default
    global_delta: float = _LOCAL_LINEAR_SPECS["global_delta"].default
    mix_decay: float = _LOCAL_LINEAR_SPECS["mix_decay"].default
    mix_ridge: float = _LOCAL_LINEAR_SPECS["mix_ridge"].default
    consolidate_after: int = _LOCAL_LINEAR_SPECS["consolidate_after"].default
    recruit_surprise: float = _LOCAL_LINEAR_SPECS["recruit_surprise"].default
    recruit_after: int = _LOCAL_LINEAR_SPECS["recruit_after"].default
    gwr: GWRParams = field(default_factory=_default_gwr)

    def __post_init__(self) -> None:
        check_fields(self, _LOCAL_LINEAR_SPECS.values(), LocalLinearError)
        if not isinstance(self.gwr, GWRParams):
            raise LocalLinearError(f"LocalLinearParams.gwr must be GWRParams, got {type(self.gwr).__name__}")
        if self.global_order > self.order:
            raise LocalLinearError(f"LocalLinearParams.global_order {self.global_order} exceeds the regressor's "
                                   f"{self.order} frames")

    def replace(self, **changes: Any) -> LocalLinearParams:
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> LocalLinearParams:
        d = dict(d)
        return cls(**{**d, "gwr": GWRParams(**d["gwr"])}) if "gwr" in d else cls(**d)


class LocalLinearPredictor:
    """Online predictor: regressor = the last `order` frames (rad, newest first); output = the
    displacements of the next `horizon` frames from the newest one, read out by `LocalLinearPGWR`.

    The pair (r(t-h), x(t-h+1..t) - x(t-h)) is learned at frame t, once its targets are observed (no
    peeking). A missing sample (None/NaN) clears the window and the queue, as in the hierarchy.
    """

    kind: ClassVar[str] = "LocalLinearPredictor"

    def __init__(self, params: LocalLinearParams | None = None, seed: int | None = 0) -> None:
        self.params = p = params or LocalLinearParams()
        rng = np.random.default_rng(seed)
        lo, hi = InputScaling(1.0, p.n_joints).window_bounds(p.order)
        out_dim = p.horizon * p.n_joints
        self.pgwr = LocalLinearPGWR(p.order * p.n_joints, out_dim, p.gwr, rng, init_low=np.concatenate(
            [lo, np.zeros(out_dim)]), init_high=np.concatenate([hi, np.zeros(out_dim)]), rate=p.rate,
            consolidate_after=p.consolidate_after, recruit_surprise=p.recruit_surprise, recruit_after=p.recruit_after)
        self._ln_at = -math.log(p.gwr.activation_threshold)
        self._motion_ms = p.noise_floor ** 2  # running mean of ||x(t) - x(t-1)||^2
        self._t = self._frames = self._missing = self._predictions = self._sequences = 0
        self._errors = ErrorTracker(p.horizon, p.n_joints, self.layer_names)
        self._init_global()
        self._clear_sequence()

    def _init_global(self) -> None:
        """The global read-out and the statistics that mix it with the local one (None without one)."""
        p = self.params
        self.linear = None
        if p.global_order:
            self.linear = RecursiveLeastSquares(p.global_order * p.n_joints + 1, p.horizon * p.n_joints,
                                                delta=p.global_delta)
        self._mix_sxx = np.zeros((p.horizon, 2, 2))  # per step: sum of [local, global] read-out products
        self._mix_sxy = np.zeros((p.horizon, 2))  # per step: sum of read-out x observed displacement
        self._mix = np.zeros((p.horizon, 2))  # the weights they give (0, 0 = hold-last until scored)

    # --- the online step --------------------------------------------------------------------------
    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        """Observe x (rad; None/NaN = missing), learn if `learn`, return (horizon, J) or None."""
        p = self.params
        t = self._t
        self._t += 1
        frame = self._as_frame(x)
        if frame is None:
            self._missing += 1
            self._errors.score(t, None, None)
            self._clear_sequence()
            return None
        self._frames += 1
        self._errors.score(t, frame, frame)  # no lower layers: P.E. = C.P.E.
        win, hist = self._win, self._hist
        if self._fill:
            step = frame - win[0]
            self._motion_ms += (1.0 - p.motion_decay) * (float(step @ step) - self._motion_ms)
        win[1:] = win[:-1]
        win[0] = frame
        self._fill = min(self._fill + 1, p.order)
        hist.append(frame)
        if learn and len(self._regs) == p.horizon and self._regs[0] is not None:
            self._learn(self._regs[0], hist)
        reg = win.reshape(-1).copy() if self._fill == p.order else None
        self._regs.append(reg)
        self._last_reg = reg
        if reg is None:
            self._outs.append(None)
            return None
        self._predictions += 1
        prediction = self._forecast(reg, record=True)
        self._errors.expect(t, prediction)
        return prediction

    def predict(self) -> np.ndarray | None:
        """The prediction of the last `step` with the current network; no state change."""
        return None if self._last_reg is None else self._forecast(self._last_reg)

    def _learn(self, reg: np.ndarray, hist: deque[np.ndarray]) -> None:
        p = self.params
        frames = np.asarray(hist)  # (horizon + 1, J): x(t-h) ... x(t)
        target = (frames[1:] - frames[0]).reshape(-1)
        if self.linear is not None:
            self._learn_global(target, *self._outs[0])
        scale = max(math.sqrt(self._motion_ms), p.noise_floor) * p.insertion_scale * math.sqrt(p.order)
        self.pgwr.distance_factor = self._ln_at / scale
        self.pgwr.learn_local(reg, target, p.neighbour_rate)

    def _learn_global(self, target: np.ndarray, outs: np.ndarray | None, phi: np.ndarray) -> None:
        """Score the two read-outs made for a regressor (features `phi`) against its now complete
        targets (the mixing statistics), then one RLS step of the global read-out."""
        p = self.params
        if outs is not None:
            by_step = outs.transpose(1, 0, 2)  # (horizon, 2, J)
            self._mix_sxx *= p.mix_decay
            self._mix_sxx += by_step @ by_step.transpose(0, 2, 1)
            self._mix_sxy *= p.mix_decay
            self._mix_sxy += (by_step @ target.reshape(p.horizon, p.n_joints, 1))[..., 0]
            self._mix = self._mix_weights()
        self.linear.update(phi, target)

    def _mix_weights(self) -> np.ndarray:
        """(horizon, 2) least-squares weights of the [local, global] read-outs per step: the 2 x 2 ridge
        normal equations of every step, solved in closed form (a new array)."""
        sxx, sxy = self._mix_sxx, self._mix_sxy
        # [d, a]: the diagonal, swapped, plus the ridge; w = ([d, a] * sxy - b * sxy swapped) / det
        da = sxx.diagonal(axis1=1, axis2=2)[:, ::-1] + self.params.mix_ridge * self.params.n_joints
        b = sxx[:, :1, 1]
        det = da[:, :1] * da[:, 1:]  # > 0 once b * b is taken off: a ridge-regularised Gram matrix is positive definite
        det -= b * b
        w = da * sxy
        w -= b * sxy[:, ::-1]
        w /= det
        return w

    def _forecast(self, reg: np.ndarray, record: bool = False) -> np.ndarray:
        """The prediction for regressor `reg`; `record` files both read-outs to be scored later."""
        p = self.params
        local = self.pgwr.predict_local(reg, p.readout_k).reshape(p.horizon, p.n_joints)
        if self.linear is not None:
            phi = window_features(reg.reshape(p.order, p.n_joints), p.global_order)
            outs = np.empty((2, p.horizon, p.n_joints))
            outs[0] = local
            outs[1] = self.linear.predict(phi).reshape(p.horizon, p.n_joints)
            if record:
                self._outs.append((outs, phi))
            local = outs[0] * self._mix[:, :1]
            local += outs[1] * self._mix[:, 1:]
        local += reg[:p.n_joints]
        return local

    def _as_frame(self, x: np.ndarray | None) -> np.ndarray | None:
        if x is None:
            return None
        frame = np.asarray(x, dtype=float)
        if frame.shape != (self.params.n_joints,):
            raise InputError(f"a frame must have shape ({self.params.n_joints},), got {frame.shape}")
        return frame if math.isfinite(frame.sum()) else None

    def _clear_sequence(self) -> None:
        p = self.params
        self._win = np.zeros((p.order, p.n_joints))
        self._fill = 0
        self._hist: deque[np.ndarray] = deque(maxlen=p.horizon + 1)
        self._regs: deque[np.ndarray | None] = deque(maxlen=p.horizon)
        # per regressor: its read-outs [local, global] and global features, to be scored and learned
        self._outs: deque[tuple[np.ndarray, np.ndarray] | None] = deque(maxlen=p.horizon)
        self._last_reg: np.ndarray | None = None

    def reset_sequence(self) -> None:
        """Sequence boundary: clear the window, the queue and pending predictions (never the network)."""
        self._clear_sequence()
        self._errors.forget_pending()
        self._sequences += 1

    def reset_errors(self) -> None:
        """Zero the C.P.E. statistics (counters of frames stay)."""
        self._errors.reset()

    # --- introspection ------------------------------------------------------------------------------
    @property
    def neuron_counts(self) -> tuple[int, ...]:
        return (self.pgwr.n_neurons,)

    layer_names: ClassVar[tuple[str, ...]] = ("pgwr",)

    @property
    def frames_seen(self) -> int:
        return self._frames

    @property
    def motion_rms(self) -> float:
        """Running RMS frame-to-frame motion (rad, over all joints) the insertion threshold follows."""
        return math.sqrt(self._motion_ms)

    def mix_weights(self) -> np.ndarray | None:
        """(horizon, 2) weights of the [local, global] read-outs per step (None without a global one)."""
        return None if self.linear is None else self._mix.copy()

    def errors(self) -> dict[str, Any]:
        """Counts, neurons (and how many of them were recruited), the motion scale, the read-outs'
        mixing weights, and C.P.E. (= P.E.) per step as the hierarchy reports it."""
        out = {"steps": self._t, "frames": self._frames, "missing": self._missing,
               "sequences": self._sequences, "predictions": self._predictions,
               "neurons": {"pgwr": self.pgwr.n_neurons}, "recruited": self.pgwr.recruited,
               "motion_rms_rad": self.motion_rms}
        if self.linear is not None:
            out["mix_weights"] = {"local": self._mix[:, 0].tolist(), "global": self._mix[:, 1].tolist()}
        return {**out, **self._errors.summary()}

    # --- persistence --------------------------------------------------------------------------------
    #: The arrays every checkpoint has; "visits" came with consolidation (without it: zeros), "readout_mse"
    #: with recruitment (without it: NaN).
    ARRAYS: ClassVar[tuple[str, ...]] = ("weights", "matrices", "counters", "edges", "win", "hist", "regs",
                                         *ErrorTracker.ARRAYS)
    GLOBAL_ARRAYS: ClassVar[tuple[str, ...]] = ("global:weights", "global:p", "mix_sxx", "mix_sxy", "outs",
                                                "out_features")

    def state(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """(JSON-able header, arrays) of the whole state; `from_state` continues bit for bit."""
        g = self.pgwr
        regs = list(self._regs)
        reg_arr = np.array([np.zeros(g.in_dim) if r is None else r for r in regs]).reshape(len(regs), g.in_dim)
        hist = np.array(list(self._hist)).reshape(len(self._hist), self.params.n_joints)
        header = {"params": self.params.to_dict(), "distance_factor": g.distance_factor,
                  "motion_ms": self._motion_ms, "fill": self._fill, "reg_present": [r is not None for r in regs],
                  "last_reg": self._last_reg is not None,
                  "counters": [self._t, self._frames, self._missing, self._predictions, self._sequences],
                  "errors": self._errors.header(), "recruited": g.recruited}
        arrays = {"weights": g.weights, "matrices": g.matrices.copy(), "visits": g.visits.copy(),
                  "readout_mse": g.readout_mse.copy(), "surprise_streaks": g.surprise_streaks.copy(),
                  "counters": g.counters.copy(),
                  "edges": g.edge_array(), "win": self._win.copy(), "hist": hist, "regs": reg_arr,
                  **{k: v.copy() for k, v in self._errors.arrays().items()}}
        if self.linear is not None:
            queued = list(self._outs)
            shape = (2, self.params.horizon, self.params.n_joints)
            features = self.linear.weights.shape[0]
            rls_header, rls_arrays = self.linear.state()
            header["global"] = {"rls": rls_header, "outs_present": [q is not None for q in queued]}
            arrays.update({f"global:{k}": v for k, v in rls_arrays.items()})
            arrays.update(mix_sxx=self._mix_sxx.copy(), mix_sxy=self._mix_sxy.copy(),
                          outs=np.array([np.zeros(shape) if q is None else q[0] for q in queued]).reshape(
                              len(queued), *shape),
                          out_features=np.array([np.zeros(features) if q is None else q[1] for q in queued]).reshape(
                              len(queued), features))
        return header, arrays

    @classmethod
    def from_state(cls, header: dict[str, Any], arrays: dict[str, np.ndarray],
                   source: str | os.PathLike[str] = "<state>") -> LocalLinearPredictor:
        """The predictor of a `state()`; CheckpointError naming `source` if it does not fit."""
        require_arrays(cls.ARRAYS, arrays, source)
        try:
            settings = header["params"]
            for added, before in _BEFORE:  # an older checkpoint keeps the learner it was written with
                if added not in settings:
                    settings = {**settings, **before}
            params = LocalLinearParams.from_dict(settings)
            model = cls.__new__(cls)
            model.params = params
            model._ln_at = -math.log(params.gwr.activation_threshold)
            model.pgwr = LocalLinearPGWR.from_parts(
                arrays["weights"], arrays["matrices"], params.gwr, edges=arrays["edges"],
                counters=arrays["counters"], match_dim=params.order * params.n_joints,
                distance_factor=float(header["distance_factor"]), rate=params.rate, delta=1e-4,
                visits=arrays.get("visits"), consolidate_after=params.consolidate_after,
                readout_mse=arrays.get("readout_mse"), recruit_surprise=params.recruit_surprise,
                recruited=int(header.get("recruited", 0)), streaks=arrays.get("surprise_streaks"),
                recruit_after=params.recruit_after)
            if model.pgwr.out_dim != params.horizon * params.n_joints:
                raise ValueError(f"outputs are {model.pgwr.out_dim}-d, parameters say "
                                 f"{params.horizon * params.n_joints}")
            model._motion_ms = float(header["motion_ms"])
            (model._t, model._frames, model._missing, model._predictions,
             model._sequences) = (int(v) for v in header["counters"])
            model._errors = ErrorTracker(params.horizon, params.n_joints, cls.layer_names)
            model._errors.restore(header["errors"], arrays)
            model._clear_sequence()
            if np.shape(arrays["win"]) != model._win.shape:
                raise ValueError(f"array 'win' has shape {np.shape(arrays['win'])}, expected {model._win.shape}")
            model._win[...] = arrays["win"]
            model._fill = int(header["fill"])
            for row in np.asarray(arrays["hist"], dtype=float).reshape(-1, params.n_joints):
                model._hist.append(row.copy())
            present = header["reg_present"]
            regs = np.asarray(arrays["regs"], dtype=float)
            if len(present) != len(regs) or len(regs) > params.horizon:
                raise ValueError(f"regressor queue of {len(regs)} entries does not fit the parameters")
            for flag, reg in zip(present, regs, strict=True):
                model._regs.append(reg.copy() if flag else None)
            model._last_reg = model._regs[-1] if header["last_reg"] else None
            model._init_global()
            if model.linear is not None:
                model._restore_global(header["global"], arrays)
        except CheckpointError:
            raise
        except (KeyError, ValueError, TypeError, IndexError) as exc:
            raise CheckpointError(f"{source}: inconsistent local-linear checkpoint: "
                                  f"{type(exc).__name__}: {exc}") from exc
        return model

    def _restore_global(self, header: dict[str, Any], arrays: dict[str, np.ndarray]) -> None:
        missing = sorted(set(self.GLOBAL_ARRAYS) - arrays.keys())
        if missing:
            raise ValueError(f"missing arrays {missing} of the global read-out")
        prefix = "global:"
        self.linear.restore(header["rls"], {k[len(prefix):]: v for k, v in arrays.items() if k.startswith(prefix)})
        for name, dest in (("mix_sxx", self._mix_sxx), ("mix_sxy", self._mix_sxy)):
            if np.shape(arrays[name]) != dest.shape:
                raise ValueError(f"array {name!r} has shape {np.shape(arrays[name])}, expected {dest.shape}")
            dest[...] = arrays[name]
        self._mix = self._mix_weights()
        present, outs = header["outs_present"], np.asarray(arrays["outs"], dtype=float)
        features = np.asarray(arrays["out_features"], dtype=float)
        shape = (len(self._regs), 2, self.params.horizon, self.params.n_joints)
        n_features = self.linear.weights.shape[0]
        if len(present) != len(outs) or outs.shape != shape or features.shape != (len(outs), n_features):
            raise ValueError(f"read-out queue of shapes {outs.shape}, {features.shape} does not fit the regressor "
                             f"queue {shape}")
        for flag, o, f in zip(present, outs, features, strict=True):
            self._outs.append((o.copy(), f.copy()) if flag else None)

    def save(self, path: str | os.PathLike[str]) -> None:
        header, arrays = self.state()
        write_checkpoint(path, self.kind, header, arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> LocalLinearPredictor:
        header, arrays = read_checkpoint(path, cls.kind, list(cls.ARRAYS))
        return cls.from_state(header, arrays, path)
