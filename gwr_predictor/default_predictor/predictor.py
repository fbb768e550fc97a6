"""The default predictor's online loop: the local-linear P-GWR (`network.py`) and a global linear
read-out, learned one frame at a time, predicting the next `horizon` frames.

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

import math
from collections import deque
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.default_predictor.network import LocalLinearPGWR
from gwr_predictor.default_predictor.params import LocalLinearParams
from gwr_predictor.learning.online_loop import OnlineLoop
from gwr_predictor.learning.persistence import Checkpointed, fill_queue, stack_queue
from gwr_predictor.learning.rls import RecursiveLeastSquares, window_features
from gwr_predictor.learning.scaling import InputScaling


class LocalLinearPredictor(OnlineLoop, Checkpointed):
    """Online predictor: regressor = the last `order` frames (rad, newest first); output = the
    displacements of the next `horizon` frames from the newest one, read out by `LocalLinearPGWR`.

    The pair (r(t-h), x(t-h+1..t) - x(t-h)) is learned at frame t, once its targets are observed (no
    peeking). A missing sample (None/NaN) clears the window and the queue, as in the hierarchy.
    """

    kind: ClassVar[str] = "LocalLinearPredictor"
    #: the global read-out (None: local read-outs only, `global_order` 0)
    linear: RecursiveLeastSquares | None
    # the sequence state `_clear_sequence` resets: window (newest first) and its fill, the frames, the
    # regressors waiting for their targets and, in step with them, their read-outs and global features
    _win: np.ndarray
    _fill: int
    _hist: deque[np.ndarray]
    _regs: deque[np.ndarray | None]
    _outs: deque[tuple[np.ndarray, np.ndarray] | None]
    _last_reg: np.ndarray | None

    def __init__(self, params: LocalLinearParams | None = None, seed: int | None = 0) -> None:
        self.params = p = params or LocalLinearParams()
        rng = np.random.default_rng(seed)
        lo, hi = InputScaling(1.0, p.n_joints).window_bounds(p.order)
        out_dim = p.horizon * p.n_joints
        self.pgwr = LocalLinearPGWR(p.order * p.n_joints, out_dim, p.gwr, rng, init_low=np.concatenate(
            [lo, np.zeros(out_dim)]), init_high=np.concatenate([hi, np.zeros(out_dim)]), rate=p.rate,
            consolidate_after=p.consolidate_after, recruit_surprise=p.recruit_surprise, recruit_after=p.recruit_after)
        self._motion_ms = p.noise_floor ** 2  # running mean of ||x(t) - x(t-1)||^2
        self._start_loop(p.horizon, p.n_joints)
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
        queued = self._outs[0] if self._outs else None
        if self.linear is not None and queued is not None:  # filed with the regressor, which is here
            self._learn_global(self.linear, target, *queued)
        scale = max(math.sqrt(self._motion_ms), p.noise_floor) * p.insertion_scale * math.sqrt(p.order)
        self.pgwr.follow_motion_scale(scale)
        self.pgwr.learn_local(reg, target, p.neighbour_rate)

    def _learn_global(self, linear: RecursiveLeastSquares, target: np.ndarray, outs: np.ndarray | None,
                      phi: np.ndarray) -> None:
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
        linear.update(phi, target)

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

    def _global_features(self, reg: np.ndarray) -> np.ndarray:
        """What the global read-out sees of regressor `reg`: its newest `global_order` frames and their changes."""
        p = self.params
        return window_features(reg.reshape(p.order, p.n_joints), p.global_order)

    def _forecast(self, reg: np.ndarray, record: bool = False) -> np.ndarray:
        """The prediction for regressor `reg`; `record` files both read-outs to be scored later."""
        p = self.params
        local = self.pgwr.predict_local(reg, p.readout_k).reshape(p.horizon, p.n_joints)  # a new array
        if self.linear is not None:
            phi = self._global_features(reg)
            outs = np.empty((2, p.horizon, p.n_joints))
            outs[0] = local
            outs[1] = self.linear.predict(phi).reshape(p.horizon, p.n_joints)
            if record:
                self._outs.append((outs, phi))
            mix = self._mix
            local *= mix[:, :1]  # outs[0] * the local weights, in the local read-out's own array
            local += outs[1] * mix[:, 1:]
        local += reg[:p.n_joints]
        return local

    def _clear_sequence(self) -> None:
        p = self.params
        self._win = np.zeros((p.order, p.n_joints))
        self._fill = 0
        self._hist = deque(maxlen=p.horizon + 1)
        self._regs = deque(maxlen=p.horizon)
        # per regressor: its read-outs [local, global] and global features, to be scored and learned
        self._outs = deque(maxlen=p.horizon)
        self._last_reg = None

    # --- introspection ------------------------------------------------------------------------------
    @property
    def neuron_counts(self) -> tuple[int, ...]:
        return (self.pgwr.n_neurons,)

    layer_names: ClassVar[tuple[str, ...]] = ("pgwr",)

    @property
    def motion_rms(self) -> float:
        """Running RMS frame-to-frame motion (rad, over all joints) the insertion threshold follows."""
        return math.sqrt(self._motion_ms)

    def mix_weights(self) -> np.ndarray | None:
        """(horizon, 2) weights of the [local, global] read-outs per step (None without a global one)."""
        return None if self.linear is None else self._mix.copy()

    def errors(self) -> dict[str, Any]:
        """Counts, neurons (how many were recruited, how many evicted at the bound), the motion scale, the read-outs'
        mixing weights, and C.P.E. (= P.E.) per step as the hierarchy reports it."""
        out = {**self._counts(), "neurons": {"pgwr": self.pgwr.n_neurons}, "recruited": self.pgwr.recruited,
               "evicted": self.pgwr.evicted, "motion_rms_rad": self.motion_rms}
        if self.linear is not None:
            out["mix_weights"] = {"local": self._mix[:, 0].tolist(), "global": self._mix[:, 1].tolist()}
        return {**out, **self._errors.summary()}

    # --- persistence --------------------------------------------------------------------------------
    PARAMS = LocalLinearParams
    PERSIST = OnlineLoop.PERSIST.extend(
        arrays=("_win", "_mix_sxx", "_mix_sxy", "_mix"), values=("_motion_ms", "_fill"),
        members={"pgwr": "", "linear": "global"},
        queues={"_regs": lambda m: (m.pgwr.in_dim,), "_hist": lambda m: (m.params.n_joints,)})

    def _save_extra(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """The queued read-outs: pairs (read-outs, features) filed in step with the regressors."""
        if self.linear is None:
            return {}, {}
        p = self.params
        present, outs = stack_queue(deque(None if q is None else q[0] for q in self._outs), (2, p.horizon, p.n_joints))
        _, features = stack_queue(deque(None if q is None else q[1] for q in self._outs), (self.linear.p.shape[0],))
        return {"outs_present": present}, {"outs": outs, "out_features": features}

    def _load_extra(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
        self._last_reg = self._regs[-1] if self._regs else None  # the newest regressor is the last queued
        if self.linear is None:
            return
        p = self.params
        outs: deque[np.ndarray | None] = deque(maxlen=p.horizon)
        features: deque[np.ndarray | None] = deque(maxlen=p.horizon)
        fill_queue(outs, header["outs_present"], arrays["outs"], (2, p.horizon, p.n_joints), "outs")
        fill_queue(features, header["outs_present"], arrays["out_features"], (self.linear.p.shape[0],), "out_features")
        if [o is not None for o in outs] != [r is not None for r in self._regs]:
            raise DefaultPredictorError("read-out queue out of step with the regressor queue")
        for o, f in zip(outs, features, strict=True):
            self._outs.append(None if o is None or f is None else (o, f))
