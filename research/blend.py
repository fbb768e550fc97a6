"""Blending online predictors per horizon step, weighted by each one's running error.

`BlendedPredictor` runs several predictors (`Predictor` protocol) side by side on the same frames and
returns, for every horizon step k, the mean of their predictions weighted by 1 / (running MSE of that
member at step k). The running MSE is computed only from predictions that have already been scored
against an observed frame: a prediction made at frame t for step k waits until frame t + k is
observed; if that frame is missing, or the sequence ends or is reset first, it is never scored. So
the weights used at frame t depend only on frames <= t (no peeking at the targets).

The GWR hierarchy is better in MAE but heavy-tailed, RLS-AR is better in MSE (research/experiments.md);
blended per step they beat both in MSE. `make_blend` builds the two pairings used in the reports.

Persistence: `save`/`load` write and read ONE checkpoint (checkpoint.py: atomic, versioned, kind
"BlendedPredictor") holding every member's full state (members must have `state()` and a class
`from_state`: Hierarchy, FlatPredictor, RLSAutoregressive), the running MSEs, the pending predictions
and the parameters, so a blend saved mid-stream continues bit for bit after `load`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from gwr_predictor.default_predictor.gate import inner_model
from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.learning.checkpoint import raise_state_error, read_checkpoint, write_checkpoint
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.hierarchy import FlatPredictor, Hierarchy
from gwr_predictor.learning.params import HierarchyParams
from gwr_predictor.learning.pending import PendingPredictions
from gwr_predictor.learning.protocol import Predictor
from gwr_predictor.parameters.spec import ParamSpec, check_fields
from gwr_predictor.pipeline.conventions import DEFAULT_HORIZON
from gwr_predictor.predictors.baselines import RLSAutoregressive, RLSParams


class BlendError(GwrPredictorError, ValueError):
    """Invalid blend parameters or members, or a member output of the wrong shape."""


_BLEND_SPECS = {spec.name: spec for spec in (
    ParamSpec("decay", 0.99, "forgetting of the running MSE per scored frame", 0.0, 1.0, lo_open=True),
    ParamSpec("floor", 1e-6, "lower bound of the MSE (rad^2)", 0.0, lo_open=True),
    ParamSpec("horizon", DEFAULT_HORIZON, "steps predicted", 1),
    ParamSpec("adapt_frozen", True, "keep scoring members when not learning"),
)}


@dataclass(frozen=True)
class BlendParams:
    """Blend settings.

    `decay`: forgetting factor of the running MSE per scored frame (1.0 = plain mean of everything
    scored; 0.99 ~ the last 100 scored frames). `floor`: lower bound of the MSE (rad^2) before it is
    inverted, so a perfect member cannot get an infinite weight. `horizon`: steps predicted (members
    must predict at least this many; extra steps are ignored). `adapt_frozen`: keep scoring members
    (and so adapting the weights) when `step` is called with learn=False; the weights are then a
    running statistic of observed errors, not learned parameters of a model.
    """

    decay: float = _BLEND_SPECS["decay"].default
    floor: float = _BLEND_SPECS["floor"].default
    horizon: int = _BLEND_SPECS["horizon"].default
    adapt_frozen: bool = _BLEND_SPECS["adapt_frozen"].default

    def __post_init__(self) -> None:
        check_fields(self, _BLEND_SPECS.values(), BlendError)


class BlendedPredictor:
    """Per-horizon-step inverse-MSE blend of several online predictors (the `Predictor` protocol).

    Every `step` calls every member's `step` with the same sample. Member predictions wait in one
    `pending.PendingPredictions` (members leading) under the frame they target, and are scored when
    that frame is observed. `_t` counts frames (missing ones too).
    """

    def __init__(self, members: Mapping[str, Predictor], params: BlendParams | None = None) -> None:
        if not members:
            raise BlendError("a blend needs at least one member")
        for name, m in members.items():
            if not (callable(getattr(m, "step", None)) and callable(getattr(m, "reset_sequence", None))):
                raise BlendError(f"member {name!r} does not implement step/reset_sequence")
        self.members: dict[str, Predictor] = dict(members)
        self.names = tuple(self.members)
        self.params = params or BlendParams()
        h, n = self.params.horizon, len(self.names)
        self.horizon = h
        self._sse = np.zeros((n, h))  # decayed sum of squared errors (mean over joints) per member, step
        self._weight = np.zeros((n, h))  # decayed number of scored predictions
        self._count = np.zeros((n, h), dtype=np.int64)  # scored predictions, undecayed
        self._t = 0
        self._pending: PendingPredictions | None = None  # allocated on the first sample (joints known)
        self._outputs: np.ndarray | None = None  # latest member outputs (members, h, joints), NaN = none
        self.reset_sequence()

    # --- protocol -------------------------------------------------------------------------------
    def reset_sequence(self) -> None:
        """Start a new sequence: members reset, pending predictions dropped (never scored)."""
        for m in self.members.values():
            m.reset_sequence()
        if self._pending is not None:
            self._pending.drop()
            self._outputs.fill(np.nan)

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        """Score pending predictions against x (if observed), step every member, blend their outputs."""
        obs = None
        if x is not None:
            obs = np.asarray(x, dtype=float)
            if obs.ndim != 1 or (self._pending is not None and obs.shape[0] != self._joints):
                joints = "joints" if self._pending is None else self._joints
                raise BlendError(f"expected a ({joints},) sample, got shape {obs.shape}")
            if self._pending is None:
                self._allocate(obs.shape[0])
            if not np.isfinite(obs).all():
                obs = None  # a missing sample, for the members too
        due = None if self._pending is None else self._pending.take(self._t)
        if due is not None and obs is not None and (learn or self.params.adapt_frozen):
            self._score(obs, *due)
        outputs = [m.step(obs, learn=learn) for m in self.members.values()]
        self._t += 1
        if self._pending is None:  # nothing observed yet: members cannot have predicted
            if any(o is not None for o in outputs):
                self._allocate(np.asarray(next(o for o in outputs if o is not None)).shape[1])
            else:
                return None
        self._store(outputs)
        return self._blend(self._outputs)

    def predict(self) -> np.ndarray | None:
        """Blend of the members' current `predict()` (only if every member has one), without stepping."""
        missing = [n for n, m in self.members.items() if not callable(getattr(m, "predict", None))]
        if missing:
            raise BlendError(f"members {missing} have no predict()")
        if self._pending is None:
            return None
        return self._blend(self._stack([m.predict() for m in self.members.values()]))  # type: ignore[attr-defined]

    # --- introspection --------------------------------------------------------------------------
    def running_mse(self) -> np.ndarray:
        """(members, horizon) running MSE (rad^2, mean over joints); NaN where nothing was scored yet."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self._weight > 0, self._sse / np.where(self._weight > 0, self._weight, 1.0), np.nan)

    def weight_matrix(self, available: np.ndarray | None = None) -> np.ndarray:
        """(members, horizon) weights, summing to 1 per step over the `available` members (default all).

        Weights are proportional to 1 / max(MSE, floor). A member not scored yet at a step gets the mean
        MSE of the members that were; if none was, the available members are weighted equally.
        """
        n, h = self._sse.shape
        avail = np.ones((n, h), dtype=bool) if available is None else np.broadcast_to(available, (n, h))
        mse = self.running_mse()
        known = np.isfinite(mse)
        n_known = known.sum(axis=0)
        mean_known = np.where(n_known > 0, np.where(known, mse, 0.0).sum(axis=0) / np.maximum(n_known, 1), 1.0)
        mse = np.where(known, mse, mean_known[None, :])
        inv = np.where(avail, 1.0 / np.maximum(mse, self.params.floor), 0.0)
        total = inv.sum(axis=0, keepdims=True)
        return np.divide(inv, total, out=np.zeros_like(inv), where=total > 0)

    def weights(self) -> dict[str, np.ndarray]:
        """Current weights per member, each (horizon,), if every member predicted."""
        w = self.weight_matrix()
        return {name: w[i].copy() for i, name in enumerate(self.names)}

    def errors(self) -> dict[str, Any]:
        """Running MSE per member (rad^2 per horizon step, NaN = not scored yet), scored counts,
        current weights, and each member's own `errors()` where it has one."""
        mse = self.running_mse()
        out: dict[str, Any] = {
            "running_mse": {n: mse[i].tolist() for i, n in enumerate(self.names)},
            "scored": {n: self._count[i].tolist() for i, n in enumerate(self.names)},
            "weights": {n: w.tolist() for n, w in self.weights().items()},
        }
        members = {n: m.errors() for n, m in self.members.items() if callable(getattr(m, "errors", None))}
        if members:
            out["members"] = members
        return out

    @property
    def neuron_counts(self) -> tuple[int, ...] | None:
        """Neuron counts of the first member that has them (for the status topic), else None."""
        for m in self.members.values():
            counts = getattr(m, "neuron_counts", None)
            if counts is not None:
                return tuple(counts)
        return None

    # --- persistence ----------------------------------------------------------------------------
    kind = "BlendedPredictor"
    _BLEND_ARRAYS = ("sse", "weight", "count")

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the blend and all its members atomically to one checkpoint (LearningError on failure)."""
        members, arrays = [], {}
        for name, m in self.members.items():
            state = getattr(m, "state", None)
            if not callable(state) or _member_class(getattr(m, "kind", None)) is None:
                raise LearningError(f"{path}: member {name!r} ({type(m).__name__}) cannot be saved: "
                                    f"supported members are {', '.join(_member_kinds())}", source=path)
            header, member_arrays = state()
            members.append({"name": name, "kind": m.kind, "header": header})
            arrays.update({f"{name}:{k}": v for k, v in member_arrays.items()})
        arrays.update({"blend:sse": self._sse, "blend:weight": self._weight, "blend:count": self._count})
        joints = None
        if self._pending is not None:
            joints = self._joints
            arrays.update({"blend:pending": self._pending.pending, "blend:valid": self._pending.valid,
                           "blend:outputs": self._outputs})
        header = {"blend": {"params": asdict(self.params), "members": members, "joints": joints,
                            "t": self._t}}
        write_checkpoint(path, self.kind, header, arrays)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> BlendedPredictor:
        """A blend written by `save`; continues exactly where it stopped. LearningError naming the file
        (and the kind it holds) if it is not a readable blend checkpoint."""
        header, arrays = read_checkpoint(path, cls.kind, [f"blend:{a}" for a in cls._BLEND_ARRAYS])
        try:
            meta = header["blend"]
            params = BlendParams(**meta["params"])
            members: dict[str, Predictor] = {}
            for entry in meta["members"]:
                name, kind = entry["name"], entry["kind"]
                member_cls = _member_class(kind)
                if member_cls is None:
                    raise LearningError(f"{path}: member {name!r} is a {kind!r}; this build restores "
                                        f"{', '.join(_member_kinds())}", source=path)
                prefix = f"{name}:"
                sub = {k[len(prefix):]: v for k, v in arrays.items() if k.startswith(prefix)}
                if kind == "RLSAutoregressive":
                    members[name] = member_cls.from_state(entry["header"], sub)
                else:
                    members[name] = member_cls.from_state(entry["header"], sub, f"{path} (member {name!r})")
            blend = cls._assemble(members, params)
            n, h = len(blend.names), blend.horizon
            for a in cls._BLEND_ARRAYS:
                if arrays[f"blend:{a}"].shape != (n, h):
                    raise ValueError(f"array blend:{a} has shape {arrays[f'blend:{a}'].shape}, expected {(n, h)}")
            blend._sse = np.array(arrays["blend:sse"], dtype=float)
            blend._weight = np.array(arrays["blend:weight"], dtype=float)
            blend._count = np.array(arrays["blend:count"], dtype=np.int64)
            if meta["joints"] is not None:
                blend._allocate(int(meta["joints"]))
                blend._t = int(meta["t"])
                ring = blend._pending
                for a, dest in zip(("pending", "valid", "outputs"), (ring.pending, ring.valid, blend._outputs),
                                   strict=True):
                    if arrays[f"blend:{a}"].shape != dest.shape:
                        raise ValueError(f"array blend:{a} has shape {arrays[f'blend:{a}'].shape}, "
                                         f"expected {dest.shape}")
                    dest[...] = arrays[f"blend:{a}"]
        except (KeyError, ValueError, TypeError, IndexError) as exc:  # BlendError, PredictorError are ValueErrors
            raise_state_error(exc, path, "inconsistent blend checkpoint")
        return blend

    @classmethod
    def _assemble(cls, members: dict[str, Predictor], params: BlendParams) -> BlendedPredictor:
        """A blend of restored members, without resetting them (as __init__ would)."""
        blend = cls.__new__(cls)
        blend.members, blend.names, blend.params = members, tuple(members), params
        blend.horizon = h = params.horizon
        n = len(members)
        blend._sse, blend._weight = np.zeros((n, h)), np.zeros((n, h))
        blend._count = np.zeros((n, h), dtype=np.int64)
        blend._t = 0
        blend._pending = blend._outputs = None
        return blend

    # --- internals ------------------------------------------------------------------------------
    def _allocate(self, joints: int) -> None:
        n, h = len(self.names), self.horizon
        self._joints = joints
        self._pending = PendingPredictions(h, joints, (n,))
        self._outputs = np.full((n, h, joints), np.nan)

    def _score(self, obs: np.ndarray, targeted: np.ndarray, valid: np.ndarray) -> None:
        """Score the member predictions (members, h, joints) due at this (observed) frame, row k made
        k + 1 frames ago, and update the MSEs."""
        err = np.mean((targeted - obs) ** 2, axis=2)  # NaN where a member did not predict
        scored = valid & np.isfinite(err)
        decay = np.where(scored, self.params.decay, 1.0)
        self._sse = decay * self._sse + np.where(scored, err, 0.0)
        self._weight = decay * self._weight + scored
        self._count += scored

    def _stack(self, outputs: list[Any]) -> np.ndarray:
        joints = self._joints
        out = np.full((len(outputs), self.horizon, joints), np.nan)
        for i, o in enumerate(outputs):
            if o is None:
                continue
            o = np.asarray(o, dtype=float)
            if o.ndim != 2 or o.shape[0] < self.horizon or o.shape[1] != joints:
                raise BlendError(f"member {self.names[i]!r} returned shape {o.shape}; "
                                 f"need at least ({self.horizon}, {joints})")
            out[i] = o[: self.horizon]
        return out

    def _store(self, outputs: list[Any]) -> None:
        """File this frame's member predictions (made at frame `_t - 1`; NaN rows = none)."""
        self._outputs = self._stack(outputs)
        self._pending.file(self._t - 1, self._outputs, np.isfinite(self._outputs).all(axis=-1))

    def _blend(self, preds: np.ndarray) -> np.ndarray | None:
        """Weighted mean over the members that predicted (all steps of a member's output, or none)."""
        avail = np.isfinite(preds).all(axis=2)  # (members, h)
        if not avail.any():
            return None
        w = self.weight_matrix(avail)
        return np.einsum("mh,mhj->hj", w, np.where(avail[:, :, None], preds, 0.0))


def _member_classes() -> dict[str, type]:
    return {c.kind: c for c in (Hierarchy, FlatPredictor, RLSAutoregressive)}


def _member_kinds() -> tuple[str, ...]:
    return tuple(_member_classes())


def _member_class(kind: Any) -> type | None:
    return _member_classes().get(kind) if isinstance(kind, str) else None


#: Registry name of each blend (research/registry.py) -> the name of its GWR member.
BLENDS = {"blend_hierarchy_rls": "hierarchy", "blend_flat_rls": "flat"}


def make_blend(kind: str = "blend_hierarchy_rls", params: Any = None, seed: int = 0, horizon: int | None = None,
               blend: BlendParams | None = None) -> BlendedPredictor:
    """A fresh blend of a GWR predictor and RLS-AR.

    `kind` "blend_hierarchy_rls" (GWR1 -> GWR2 -> P-GWR) or "blend_flat_rls" (P-GWR alone on raw
    frames), the registry's names; `params` the `HierarchyParams` (None = defaults); `horizon`
    defaults to the params' horizon (and, if given, overrides it for the GWR member too). The RLS
    regressor spans the hierarchy's `span` frames.
    """

    if kind not in BLENDS:
        raise BlendError(f"unknown blend kind {kind!r}; choose from {', '.join(BLENDS)}")
    params = params or HierarchyParams()
    if horizon is not None and horizon != params.horizon:
        params = params.replace(horizon=horizon)
    gwr_cls = Hierarchy if BLENDS[kind] == "hierarchy" else FlatPredictor
    members = {BLENDS[kind]: gwr_cls(params, seed=seed),
               "rls": RLSAutoregressive(RLSParams(order=params.span, forgetting=0.999), params.horizon,
                                        params.n_joints)}
    bp = blend or BlendParams()
    if bp.horizon != params.horizon:
        bp = BlendParams(decay=bp.decay, floor=bp.floor, horizon=params.horizon, adapt_frozen=bp.adapt_frozen)
    return BlendedPredictor(members, bp)


def load_blend(kind: str, path: str | os.PathLike[str]) -> BlendedPredictor:
    """The blend `kind` (a `BLENDS` name) saved at `path`; a LearningError with `kind_mismatch` if it holds
    other members."""
    if kind not in BLENDS:
        raise BlendError(f"unknown blend kind {kind!r}; choose from {', '.join(BLENDS)}")
    model = BlendedPredictor.load(path)
    expected = (BLENDS[kind], "rls")
    if tuple(model.names) != expected:
        raise LearningError(f"{path}: holds a blend of {list(model.names)}, expected one of {list(expected)}",
                            source=path, found=model.names, expected=kind)
    return model


def gwr_member(model: Any) -> Any:
    """The GWR learner inside `model`: the model itself, the gate's model, or the blend's member that
    has neurons."""

    if isinstance(model, BlendedPredictor):
        return next(m for m in model.members.values() if getattr(m, "neuron_counts", None) is not None)
    return inner_model(model)
