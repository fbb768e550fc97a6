"""The online learner: GWR1 -> GWR2 -> P-GWR (Sec. III-B..D), one frame at a time.

`step` at time t, with frame x(t) observed (scaled by `input_scale` inside), in four named steps:

1. `_encode`: GWR1 learns x(t) (Eqs. 1-4); its representative neuron (the inserted one, else the
   BMU after the update) enters window 1, newest first; once window 1 holds tau1 entries, their
   concatenation o1(t) (Eq. 5) is GWR2's input; GWR2's representative enters window 2, whose
   concatenation o2(t) (Eq. 5) is the P-GWR regressor x_in(t) (Eq. 7; 72 values by default).
2. score: the predictions made earlier for frame t: C.P.E. against x(t), P.E. against its GWR1
   representative (the target "as represented by the hierarchy").
3. `_learn_pgwr` (Eqs. 8-9): only a pair whose target has now been observed (Eq. 7):
   (x_in(t-1), x(t)) in recursive mode, (x_in(t-h), x(t-h+1) + ... + x(t)) in vector mode. The
   P-GWR never sees a frame before its step.
4. `_predict` (Eq. 10): the output weights of x_in(t)'s BMU are x(t+1) (vector mode: x(t+1..t+h));
   in recursive mode each predicted frame is fed back: GWR1 BMU -> window 1 -> GWR2 BMU ->
   window 2 -> P-GWR BMU (no learning on predictions).

A missing sample (None or non-finite values) is a gap: windows and the queue of regressors are
cleared (a concatenation never bridges unrelated frames) and the gap is counted; predictions made
before it are still scored against the frames they target. `reset_sequence()` does the same at a
sequence boundary and also drops those pending predictions. Networks are never cleared by either.

`FlatPredictor` is the ablation without GWR1/GWR2: the regressor is the last p scaled raw frames.
"""

from __future__ import annotations

import copy
from collections import deque
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.gwr import GWR
from gwr_predictor.learning.online_loop import OnlineLoop
from gwr_predictor.learning.params import LAYERS, HierarchyParams
from gwr_predictor.learning.persistence import Checkpointed, Persist, Persistent
from gwr_predictor.learning.predictive_gwr import PredictiveGWR
from gwr_predictor.learning.scaling import InputScaling


class _Window(Persistent):
    """Eq. 5's window in time: the last `tau` rows, newest first; `flat` (a view) is their
    concatenation o(t) = w_b(t) + w_b(t-1) + ... + w_b(t-tau+1) once `full`."""

    __slots__ = ("fill", "rows")
    PERSIST = Persist(arrays=("rows",), values=("fill",))

    def __init__(self, tau: int, dim: int) -> None:
        self.rows = np.zeros((tau, dim))
        self.fill = 0

    @property
    def flat(self) -> np.ndarray:
        """The rows as one vector: a view taken on each use (a stored view would not follow a deep copy)."""
        return self.rows.reshape(-1)

    def push(self, row: np.ndarray) -> bool:
        """Shift `row` in as the newest entry; True when the window holds `tau` entries."""
        rows = self.rows
        rows[1:] = rows[:-1]
        rows[0] = row
        self.fill = min(self.fill + 1, len(rows))
        return self.fill == len(rows)


class _OnlinePredictor(OnlineLoop, Checkpointed):
    """Shared online loop of `Hierarchy` and `FlatPredictor`: gaps, delayed targets, predictions,
    bookkeeping, persistence. Subclasses encode frames into regressors."""

    kind: ClassVar[str]
    layer_names: ClassVar[tuple[str, ...]]
    pgwr: PredictiveGWR
    # the sequence state `_clear_sequence` resets: the last scaled frames (oldest first) and their
    # fill, the regressors waiting for their targets, the newest regressor
    _xbuf: np.ndarray
    _xfill: int
    _regs: deque[np.ndarray | None]
    _last_reg: np.ndarray | None

    def __init__(self, params: HierarchyParams | None = None, seed: int | None = 0) -> None:
        self.params = HierarchyParams() if params is None else params
        if not isinstance(self.params, HierarchyParams):
            raise TypeError(f"params must be HierarchyParams, got {type(self.params).__name__}")
        self._rng = np.random.default_rng(seed)
        self._configure()
        for name in self.layer_names:
            setattr(self, name, self._new_layer(name))
        self._frozen: frozenset[str] = frozenset()
        self._start_loop(self.params.horizon, self.params.n_joints)
        self._clear_sequence()

    def _configure(self) -> None:
        p = self.params
        self.scaling = InputScaling(p.input_scale, p.n_joints, p.normalise_distance)
        self._scale = p.input_scale
        self._target_steps = p.horizon if p.mode == "vector" else 1
        self._delta = p.target == "delta"
        self._readout_k = p.readout_k
        self._target = np.empty(self._target_steps * p.n_joints)

    # --- subclass hooks -------------------------------------------------------------------------
    def _new_layer(self, name: str) -> GWR:
        raise NotImplementedError

    def _clear_windows(self) -> None:
        raise NotImplementedError

    def _encode(self, xs: np.ndarray, learn: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """Feed one scaled frame; returns (its representation, scaled; the regressor x_in(t) or None)."""
        raise NotImplementedError

    def _rollout(self, first: np.ndarray, out: np.ndarray) -> None:
        """Recursive mode: fill out[1:] from the first predicted (scaled) frame."""
        raise NotImplementedError

    # --- the online step ------------------------------------------------------------------------
    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        """Observe frame x (radians; None/NaN = missing), learn if `learn`, and return the predictions
        (horizon, n_joints) in radians for t+1..t+h, or None when the windows are not full yet."""
        t = self._t
        self._t += 1
        frame = self._as_frame(x)
        if frame is None:
            self._gap(t)
            return None
        self._frames += 1
        xs = frame * self._scale  # x(t) in the model's units
        represented, x_in = self._encode(xs, learn)  # 1. x(t) -> GWR1 -> GWR2 -> x_in(t) (Eqs. 1-5, 7)
        self._errors.score(t, frame, represented / self._scale)  # 2. P.E., C.P.E. of the predictions for t
        self._observe(xs)  # x(t) completes the target of an earlier regressor
        if learn and "pgwr" not in self._frozen:
            self._learn_pgwr()  # 3. (x_in(t-k), x(t-k+1..t)) (Eqs. 7-9)
        self._regs.append(x_in)
        self._last_reg = x_in
        if x_in is None:
            return None  # the windows are not full yet
        prediction = self._predict(x_in, record=True)  # 4. x(t+1..t+h) (Eq. 10)
        self._errors.expect(t, prediction)
        self._predictions += 1
        return prediction

    def predict(self) -> np.ndarray | None:
        """The predictions from the current windows (as the last `step` returned, with the current
        networks); no learning, no state change."""
        return None if self._last_reg is None else self._predict(self._last_reg, record=False)

    def _gap(self, t: int) -> None:
        """A missing frame: the predictions for t are dropped unscored and the windows restart,
        so that no concatenation bridges the gap."""
        self._missing += 1
        self._errors.score(t, None, None)
        self._clear_sequence()

    def _observe(self, xs: np.ndarray) -> None:
        """Keep the last `_target_steps` + 1 scaled frames, oldest first: the targets of the pair
        learned now and, for delta targets, the frame they are measured from."""
        buf = self._xbuf
        buf[:-1] = buf[1:]
        buf[-1] = xs
        self._xfill = min(self._xfill + 1, len(buf))

    def _learn_pgwr(self) -> None:
        """Eqs. 8-9 on the newest pair whose output is fully observed (Eq. 7, no peeking): x_in(t-k)
        with x_out = x(t-k+1) + ... + x(t), k = 1 (recursive) or h (vector); with delta targets
        x_out holds each frame's displacement from x(t-k)."""
        k = self._target_steps
        if len(self._regs) < k or self._xfill < k + self._delta:
            return
        x_in = self._regs[-k]
        if x_in is None:
            return
        frames = self._xbuf  # x(t-k) .. x(t)
        if self._delta:
            x_out = self._target
            np.subtract(frames[1:], frames[0], out=x_out.reshape(k, -1))
        else:
            x_out = frames[1:].reshape(-1)
        # in recursive mode the P-GWR has not changed since `_predict` searched this very regressor
        # last frame: the affinity it kept is reused (`GWR.search_keep`)
        self.pgwr.learn_unchecked(x_in, x_out)

    def _predict(self, x_in: np.ndarray, record: bool) -> np.ndarray:
        """x(t+1..t+h) in radians from the regressor x_in(t): the output weights of its BMU (Eqs. 8,
        10; or the blend of its `readout_k` nearest), all h frames at once in vector mode, else the
        first frame, the rest fed back (`_rollout`). Delta targets add offsets to x(t)."""
        p = self.params
        pg = self.pgwr
        # recursive mode: the affinity is kept for the P-GWR's next learning step, which is on this
        # very regressor (see `_learn_pgwr`); vector mode learns an older one
        aff = pg.search_keep(x_in) if self._target_steps == 1 else None
        y = pg.blended_output(x_in, self._readout_k, record, affinity=aff)
        if record:
            self._errors.quantization("pgwr", pg.last_distance / self._scale)
        out = np.empty((p.horizon, p.n_joints))
        if p.mode == "vector":
            out.reshape(-1)[:] = y
            if self._delta:  # offsets from the newest observed frame
                out += self._xbuf[-1]
        else:
            out[0] = y
            if self._delta:
                out[0] += self._xbuf[-1]
            if p.horizon > 1:
                self._rollout(out[0], out)
        out /= self._scale
        return out

    def _readout(self, reg: np.ndarray, prev: np.ndarray, out: np.ndarray) -> None:
        """Roll-out step: the P-GWR's next frame for regressor `reg` into `out` (scaled); with delta
        targets the output is added to the previous (predicted) frame `prev`."""
        pg = self.pgwr
        y = pg.output_row(pg.nearest(reg)) if self._readout_k == 1 else pg.blended_output(reg, self._readout_k)
        if self._delta:
            np.add(prev, y, out=out)
        else:
            out[:] = y

    def _match(self, net: GWR, name: str, x: np.ndarray, learn: bool) -> int:
        """One GWR step on x (Eqs. 1-4), or only its BMU if frozen / not learning; returns the
        representative neuron: the one inserted, else the BMU."""
        if learn and name not in self._frozen:
            b = net.learn_unchecked(x)
            idx = net.last_inserted if net.last_inserted >= 0 else b
        else:
            idx = net.match_unchecked(x)
        self._errors.quantization(name, net.last_distance / self._scale)
        return idx

    # --- sequences and layers -------------------------------------------------------------------
    def _clear_sequence(self) -> None:
        self._clear_windows()
        self._xbuf = np.zeros((self._target_steps + 1, self.params.n_joints))
        self._xfill = 0
        self._regs = deque(maxlen=self._target_steps)
        self._last_reg = None

    def freeze_layers(self, which: tuple[str, ...] | list[str]) -> None:
        """Stop learning in exactly these layers (they still match); () unfreezes all."""
        unknown = set(which) - set(self.layer_names)
        if unknown:
            raise LearningError(f"unknown layers {sorted(unknown)}; layers are {self.layer_names}")
        self._frozen = frozenset(which)

    @property
    def frozen_layers(self) -> tuple[str, ...]:
        return tuple(n for n in self.layer_names if n in self._frozen)

    def reset_layer(self, name: str, params: Any = None) -> None:
        """Replace one layer by a fresh two-neuron network (optionally with new GWRParams), e.g. to
        re-learn the P-GWR on frozen lower layers with another a_T. Windows are cleared."""
        if name not in self.layer_names:
            raise LearningError(f"unknown layer {name!r}; layers are {self.layer_names}")
        if params is not None:
            self.params = self.params.replace(**{name: params})
        setattr(self, name, self._new_layer(name))
        self._clear_sequence()
        self._errors.forget_pending()

    @property
    def horizon(self) -> int:
        return self.params.horizon

    @property
    def neuron_counts(self) -> tuple[int, ...]:
        """Neurons per layer, in `layer_names` order."""
        return tuple(getattr(self, n).n_neurons for n in self.layer_names)

    def errors(self) -> dict[str, Any]:
        """Bookkeeping: counts, neurons (and how many were evicted at the layers' bounds), quantization errors
        (rad, Euclidean over a layer's input, last and mean), P.E./C.P.E. (MSE rad^2 per horizon step, their
        means, how many scored)."""
        return {**self._counts(), "neurons": dict(zip(self.layer_names, self.neuron_counts, strict=True)),
                "evicted": sum(getattr(self, n).evicted for n in self.layer_names), **self._errors.summary()}

    # --- persistence ----------------------------------------------------------------------------
    PARAMS = HierarchyParams
    PERSIST = OnlineLoop.PERSIST.extend(arrays=("_xbuf",), values=("_xfill",),
                                        queues={"_regs": lambda m: (m.pgwr.in_dim,)})

    def _save_extra(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        return {"rng": self._rng.bit_generator.state, "frozen": sorted(self._frozen)}, {}

    def _load_extra(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
        self.freeze_layers(tuple(header["frozen"]))
        self._last_reg = self._regs[-1] if self._regs else None  # the newest regressor is the last queued
        self._rng.bit_generator.state = header["rng"]


class Hierarchy(_OnlinePredictor):
    """GWR1 -> GWR2 -> P-GWR learning online and predicting `horizon` frames at every step."""

    kind = "Hierarchy"
    layer_names = LAYERS
    PERSIST = _OnlinePredictor.PERSIST.extend(members={"gwr1": "gwr1", "gwr2": "gwr2", "pgwr": "pgwr",
                                                       "_window1": "win1", "_window2": "win2"})
    gwr1: GWR
    gwr2: GWR

    def _new_layer(self, name: str) -> GWR:
        p, sc, rng = self.params, self.scaling, self._rng
        if name == "gwr1":
            lo, hi = sc.window_bounds(1)
            return GWR(p.n_joints, p.gwr1, rng, init_low=lo, init_high=hi, distance_factor=sc.distance_factor(1))
        if name == "gwr2":
            lo, hi = sc.window_bounds(p.tau1)
            return GWR(p.gwr2_dim, p.gwr2, rng, init_low=lo, init_high=hi,
                       distance_factor=sc.distance_factor(p.tau1))
        frames = p.tau1 * p.tau2
        return _new_pgwr(p, sc, rng, frames, p.regressor_dim)

    def _clear_windows(self) -> None:
        p = self.params
        self._window1 = _Window(p.tau1, p.n_joints)  # of GWR1's representatives: GWR2's input o1(t)
        self._window2 = _Window(p.tau2, p.gwr2_dim)  # of GWR2's representatives: x_in(t) = o2(t)
        self._roll1 = np.empty((p.horizon - 1 + p.tau1, p.n_joints))  # roll-out scratch (see _rollout)
        self._roll2 = np.empty((p.horizon - 1 + p.tau2, p.gwr2_dim))
        self._roll_views = self._views_of_scratch()

    def _views_of_scratch(self) -> tuple[list[np.ndarray], ...]:
        """Per start row s of the roll-out scratch: the row written there and the window starting there
        (flattened), made once per sequence rather than sliced in every roll-out step."""
        p = self.params
        f1, f2 = self._roll1.reshape(-1), self._roll2.reshape(-1)
        n1, n2, d2 = p.tau1 * p.n_joints, p.tau2 * p.gwr2_dim, p.gwr2_dim
        starts = range(p.horizon - 1)
        return (list(self._roll1), [f1[s * p.n_joints:s * p.n_joints + n1] for s in starts],
                list(self._roll2), [f2[s * d2:s * d2 + n2] for s in starts])

    def __deepcopy__(self, memo: dict[int, Any]) -> Hierarchy:
        """A deep copy whose roll-out views view its own scratch (copied views would be detached from it)."""
        new = type(self).__new__(type(self))
        memo[id(self)] = new
        for name, value in self.__dict__.items():
            if name != "_roll_views":
                new.__dict__[name] = copy.deepcopy(value, memo)
        new._roll_views = new._views_of_scratch()
        return new

    def _encode(self, xs: np.ndarray, learn: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """x(t) -> GWR1 -> window 1 -> GWR2 -> window 2: (x(t) as GWR1 represents it, x_in(t) or None)."""
        g1, g2, w1, w2 = self.gwr1, self.gwr2, self._window1, self._window2
        b1 = self._match(g1, "gwr1", xs, learn)  # GWR1 on x(t) (Eqs. 1-4)
        full = w1.push(g1.weight_row(b1))  # its representative enters window 1
        represented = w1.rows[0].copy()
        if not full:
            return represented, None
        b2 = self._match(g2, "gwr2", w1.flat, learn)  # GWR2 on o1(t), window 1's concatenation (Eq. 5)
        if not w2.push(g2.weight_row(b2)):  # its representative enters window 2
            return represented, None
        return represented, w2.flat.copy()  # x_in(t) = o2(t), window 2's concatenation (Eqs. 5, 7)

    def _rollout(self, first: np.ndarray, out: np.ndarray) -> None:
        """Each roll-out step is a chain of three BMU searches. The windows slide over two buffers
        holding the current windows at their end, newest first: the window after k steps is the
        contiguous slice starting k rows before it, so no step copies or shifts a window. The ~85 %
        of a step spent in the three matrix-vector products is kept as is (their exact operands give
        the exact results); the rest is trimmed: views made once per sequence, no per-step slicing."""
        h = len(out)
        s = h - 1
        rows1, wins1, rows2, wins2 = self._roll_views
        self._roll1[s:] = self._window1.rows
        self._roll2[s:] = self._window2.rows
        # the two lower searches inlined (nothing learns during a roll-out): one product + argmax each
        a1, x1, o1, w1 = self.gwr1.search_views()
        a2, x2, o2, w2 = self.gwr2.search_views()
        q1, q2 = x1[:-1], x2[:-1]  # where the queries go ([query | -1/2] is the product's operand)
        dot = np.dot
        bmu_readout = self._readout_k == 1  # the BMU read-out (Eq. 10), inlined as well
        a3, x3, o3, _ = self.pgwr.search_views()  # read-only views, used by the BMU read-out only
        q3, wo, delta, readout = x3[:-1], self.pgwr.weights_out, self._delta, self._readout
        prev = out[0]
        for k in range(1, h):  # predicted frame -> GWR1 BMU -> GWR2 BMU -> P-GWR read-out
            s -= 1
            q1[...] = prev
            rows1[s][...] = w1[dot(a1, x1, out=o1).argmax()]  # GWR1's BMU of x(t+k) enters window 1
            q2[...] = wins1[s]  # o1(t+k) (Eq. 5)
            rows2[s][...] = w2[dot(a2, x2, out=o2).argmax()]  # GWR2's BMU of o1(t+k) enters window 2
            cur = out[k]
            if bmu_readout:
                q3[...] = wins2[s]  # x_in(t+k) (Eq. 7)
                cur[...] = wo[dot(a3, x3, out=o3).argmax()]  # w_out of its BMU: x(t+k+1) (Eqs. 8, 10)
                if delta:
                    cur += prev
            else:
                readout(wins2[s], prev, cur)
            prev = cur


class FlatPredictor(_OnlinePredictor):
    """The P-GWR alone on raw frames (ablation): regressor = the last `order` scaled frames, newest
    first, the span of the hierarchy's regressor (tau1 + tau2 - 1 frames)."""

    kind = "FlatPredictor"
    layer_names = ("pgwr",)
    PERSIST = _OnlinePredictor.PERSIST.extend(members={"pgwr": "pgwr", "_window": "win"})

    @property
    def order(self) -> int:
        return self.params.span

    def _new_layer(self, name: str) -> GWR:
        p = self.params
        return _new_pgwr(p, self.scaling, self._rng, self.order, p.n_joints * self.order)

    def _clear_windows(self) -> None:
        self._window = _Window(self.order, self.params.n_joints)  # of raw frames: x_in(t) (Eq. 7)

    def _encode(self, xs: np.ndarray, learn: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """x(t) enters the window of raw frames; x_in(t) once it holds `order` frames."""
        return xs, (self._window.flat.copy() if self._window.push(xs) else None)

    def _rollout(self, first: np.ndarray, out: np.ndarray) -> None:
        w = self._window.rows.copy()
        flat = w.reshape(-1)
        for k in range(1, len(out)):
            w[1:] = w[:-1]
            w[0] = out[k - 1]
            self._readout(flat, out[k - 1], out[k])


def _new_pgwr(p: HierarchyParams, sc: InputScaling, rng: np.random.Generator, frames: int,
              in_dim: int) -> PredictiveGWR:
    """A P-GWR whose random neurons lie inside the joint limits, in and out."""
    lo_in, hi_in = sc.window_bounds(frames)
    lo_out, hi_out = sc.window_bounds(p.output_dim // p.n_joints)
    if p.target == "delta":  # displacements: initial neurons predict "no movement"
        lo_out = hi_out = np.zeros_like(lo_out)
    return PredictiveGWR(in_dim, p.output_dim, p.pgwr, rng, init_low=np.concatenate([lo_in, lo_out]),
                         init_high=np.concatenate([hi_in, hi_out]), distance_factor=sc.distance_factor(frames))
