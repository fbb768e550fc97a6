"""Simple online predictors the hierarchy has to beat, with the same `step`/`reset_sequence` protocol.

- `HoldLast`: the robot simply repeats the last seen pose (what a system without prediction does).
- `ConstantVelocity`: extrapolates the velocity of the last few observed frames.
- `RLSAutoregressive`: a multivariate linear AR model over the last p frames + bias, learned online by
  recursive least squares with forgetting; multi-step predictions by feeding predictions back, as
  the hierarchy does in recursive mode. p defaults to the hierarchy's effective regressor length.

All learn only from what they have observed: a step with x None (or non-finite) is a missing sample.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.learning.online_loop import frame_or_none
from gwr_predictor.learning.persistence import Checkpointed, Persist, params_from_json
from gwr_predictor.parameters.spec import ParamSpec, check_fields
from gwr_predictor.pipeline.conventions import DEFAULT_HORIZON
from gwr_predictor.predictors.errors import PredictorError
from gwr_predictor.robot.nao import ARM_JOINTS

N_JOINTS = len(ARM_JOINTS)


def observation(x: np.ndarray | None, joints: int = N_JOINTS) -> np.ndarray | None:
    """A finite (joints,) float vector, or None for a missing sample (`frame_or_none`, raising
    PredictorError for a sample of another size)."""
    return frame_or_none(x, joints, PredictorError)


def _check_horizon(horizon: int) -> None:
    if int(horizon) != horizon or horizon < 1:
        raise PredictorError(f"horizon must be a positive integer, got {horizon!r}")


class HoldLast:
    """Predicts that the last observed pose persists: the no-compensation reference."""

    def __init__(self, horizon: int = DEFAULT_HORIZON, joints: int = N_JOINTS) -> None:
        _check_horizon(horizon)
        self.horizon, self.joints = int(horizon), joints
        self._last: np.ndarray | None = None

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        obs = observation(x, self.joints)
        if obs is not None:
            self._last = obs.copy()
        if self._last is None:
            return None
        return np.repeat(self._last[None, :], self.horizon, axis=0)

    def reset_sequence(self) -> None:
        self._last = None


class ConstantVelocity:
    """Extrapolates the velocity of the last `window` observed frames (least-squares slope against
    their frame indices, so gaps are handled). `window=2` is the classic two-point difference, which
    amplifies sensor noise; a longer window trades that noise for lag."""

    def __init__(self, horizon: int = DEFAULT_HORIZON, joints: int = N_JOINTS, window: int = 2) -> None:
        _check_horizon(horizon)
        if int(window) != window or window < 2:
            raise PredictorError(f"window must be an integer >= 2, got {window!r}")
        self.horizon, self.joints, self.window = int(horizon), joints, int(window)
        self.reset_sequence()

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        self._t += 1
        obs = observation(x, self.joints)
        if obs is not None:
            self._frames.append(obs.copy())
            self._times.append(self._t)
            if len(self._frames) > self.window:
                del self._frames[0], self._times[0]
        if not self._frames:
            return None
        last, last_t = self._frames[-1], self._times[-1]
        velocity = np.zeros(self.joints)
        if len(self._frames) > 1:
            t = np.asarray(self._times, dtype=float)
            t -= t.mean()
            velocity = t @ np.asarray(self._frames) / (t @ t)
        ahead = (self._t - last_t) + np.arange(1, self.horizon + 1, dtype=float)
        return last[None, :] + ahead[:, None] * velocity[None, :]

    def reset_sequence(self) -> None:
        self._t = 0
        self._frames: list[np.ndarray] = []
        self._times: list[int] = []


_RLS_SPECS = {spec.name: spec for spec in (
    ParamSpec("order", 12, "frames in the regressor", 1, 64),
    ParamSpec("forgetting", 1.0, "RLS forgetting factor per learned pair (1: fit everything seen)", 0.9, 1.0),
    ParamSpec("delta", 1.0, "initial P = delta I (prior variance of the weights)", 0.0, lo_open=True),
    ParamSpec("prior", "hold", "where the weights start", choices=("hold", "zero")),
    ParamSpec("max_trace", 1e6, "P is reset when its trace exceeds this (wind-up)", 0.0, lo_open=True),
)}


@dataclass(frozen=True)
class RLSParams:
    """Recursive least squares settings; the defaults are RLS-AR's in every report and in the default
    predictor, chosen by `gwr-predictor experiment tune` on the demonstrator's tuning recordings (seed 7,
    in no reported figure): 12 frames, no forgetting.

    `delta` is the initial P = delta * I (prior variance of the weights): larger learns faster at first.
    `prior` "hold" starts the weights at hold-last (identity on the newest frame), "zero" at zero.
    `max_trace` bounds trace(P): with forgetting and poorly exciting data P winds up, so it is reset.
    """

    SPECS: ClassVar[dict[str, ParamSpec]] = _RLS_SPECS
    order: int = _RLS_SPECS["order"].default
    forgetting: float = _RLS_SPECS["forgetting"].default
    delta: float = _RLS_SPECS["delta"].default
    prior: str = _RLS_SPECS["prior"].default
    max_trace: float = _RLS_SPECS["max_trace"].default

    def __post_init__(self) -> None:
        check_fields(self, _RLS_SPECS.values(), PredictorError)


class RLSAutoregressive(Checkpointed):
    """Online linear AR(p) predictor of all joints at once: x(t+1) = W^T [x(t), ..., x(t-p+1), 1].

    One P matrix is shared by the joints (they share the regressor), so an update costs O((pJ)^2).
    The regressor of a new sequence is padded with its first frame so predictions start at once;
    padded or imputed (missing-sample) entries are never learned from.
    """

    def __init__(self, params: RLSParams | None = None, horizon: int = DEFAULT_HORIZON,
                 joints: int = N_JOINTS) -> None:
        _check_horizon(horizon)
        self.params = params or RLSParams()
        self.horizon, self.joints = int(horizon), joints
        self.dim = self.params.order * joints + 1
        self.weights_ = self._prior_weights()
        self.p_: np.ndarray = self.params.delta * np.eye(self.dim)
        self.updates_ = 0
        self.resets_ = 0
        self.reset_sequence()

    def _prior_weights(self) -> np.ndarray:
        w = np.zeros((self.dim, self.joints))
        if self.params.prior == "hold":
            w[: self.joints] = np.eye(self.joints)
        return w

    def reset_sequence(self) -> None:
        self._buf: np.ndarray = np.zeros((self.params.order, self.joints))  # newest first
        self._real: np.ndarray = np.zeros(self.params.order, dtype=bool)  # observed (not padded/imputed)
        self._started = False

    def _regressor(self, buf: np.ndarray) -> np.ndarray:
        return np.concatenate([buf.ravel(), [1.0]])

    def _push(self, frame: np.ndarray, real: bool) -> None:
        self._buf[1:] = self._buf[:-1]
        self._real[1:] = self._real[:-1]
        self._buf[0], self._real[0] = frame, real

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        obs = observation(x, self.joints)
        if not self._started:
            if obs is None:
                return None
            self._buf[:] = obs
            self._real[:] = False
            self._real[0] = True
            self._started = True
            return self.predict()
        if obs is None:
            self._push(self._regressor(self._buf) @ self.weights_, real=False)
        else:
            if learn and self._real.all():
                self._update(self._regressor(self._buf), obs)
            self._push(obs, real=True)
        return self.predict()

    def predict(self) -> np.ndarray | None:
        """Predictions (horizon, J) for the next frames, by feeding each one back into the regressor."""
        if not self._started:
            return None
        reg = self._regressor(self._buf)  # [x(t), x(t-1), ..., 1], shifted by a frame per step
        out = np.empty((self.horizon, self.joints))
        j = self.joints
        for k in range(self.horizon):
            np.matmul(reg, self.weights_, out=out[k])  # `out[k] = reg @ W` without the temporary
            reg[j:-1] = reg[:-j - 1]  # numpy copies overlapping slices as if through a buffer
            reg[:j] = out[k]
        return out

    def _update(self, phi: np.ndarray, target: np.ndarray) -> None:
        lam = self.params.forgetting
        p_phi = self.p_ @ phi
        gain = p_phi / (lam + float(phi @ p_phi))  # a float: the sum without a numpy scalar's overhead
        column = gain[:, None]  # outer products by broadcasting: np.outer's products, without its wrapper
        self.weights_ += column * (target - phi @ self.weights_)
        p = self.p_ - column * p_phi
        if lam != 1.0:  # x / 1 is x: no pass over P without forgetting
            p /= lam
        self.p_ = 0.5 * (p + p.T)
        self.updates_ += 1
        if not np.isfinite(self.weights_).all():
            self.weights_ = self._prior_weights()
            self._reset_p()
        elif not np.isfinite(self.p_).all() or np.trace(self.p_) > self.params.max_trace:
            self._reset_p()

    def _reset_p(self) -> None:
        self.p_ = self.params.delta * np.eye(self.dim)
        self.resets_ += 1

    # --- persistence (used by the blend's checkpoint) -------------------------------------------
    kind: ClassVar[str] = "RLSAutoregressive"
    PARAMS = RLSParams
    STATE_ERROR = PredictorError
    PERSIST = Persist(arrays=("weights_", "p_", "_buf", "_real"),
                      values=("horizon", "joints", "updates_", "resets_", "_started"))

    @classmethod
    def _fresh(cls, header: Mapping[str, Any]) -> RLSAutoregressive:
        return cls(params_from_json(RLSParams, header["params"]), int(header["horizon"]), int(header["joints"]))


def make_baselines(horizon: int = DEFAULT_HORIZON, order: int = 5) -> dict[str, object]:
    """Fresh instances of every baseline, keyed by the names used in reports. The constant-velocity
    slope spans `order` frames (the hierarchy's regressor length)."""
    return {
        "hold": HoldLast(horizon),
        "const_velocity": ConstantVelocity(horizon, window=max(order, 2)),
        "rls_ar": RLSAutoregressive(RLSParams(), horizon),
    }
