"""One generic persistence for every stateful class: a class declares what it holds (`Persist`), and
this module turns that into a checkpoint's (JSON header, named arrays) and back; `checkpoint.py`
writes and reads the file.

Why declarations instead of a state/from_state pair per class: the layout of every checkpoint is
then made in one place, and a loaded model is always a fresh one built from its saved parameters
with the saved state copied in, so every fixed-size array is checked against the shape and dtype
those parameters give it, by the same code for every class.

Layout (what `state` returns): header `params` (top-level classes), one header key per plain value
and one array per array, each named by its attribute without leading or trailing underscores; a
member (a stateful object held by an attribute) under its name: its arrays as `<name>.<array>`, its
header as `header[<name>]` (the name "" merges the member into its owner). Queues of optional rows
(`Persist.queues`) are one stacked array plus `<name>_present`. What is none of these (a GWR's
variable-size network, a random generator, pairs of arrays in one queue) goes through two small
hooks, `_save_extra` and `_load_extra`.
"""

from __future__ import annotations

import dataclasses
import os
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, NoReturn, TypeVar

import numpy as np

from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.learning.checkpoint import raise_state_error, read_checkpoint, require_arrays, write_checkpoint
from gwr_predictor.learning.errors import LearningError

Header = dict[str, Any]
Arrays = dict[str, np.ndarray]
_C = TypeVar("_C", bound="Checkpointed")


@dataclass(frozen=True)
class Persist:
    """What a class holds, by attribute name. `arrays`: fixed-shape arrays (shape and dtype set by
    the constructor; a file's array must match). `values`: JSON-able plain values (int, float, bool,
    str, dicts of them), read back as the type the fresh object holds. `optional`: arrays that may be
    None (float). `members`: attribute -> name of stateful members (`Persistent`, or None for none).
    `queues`: attribute -> row shape (of the object) of deques of rows or None. `nan_ok`: arrays (and
    values) where NaN means "none yet"; every other float array, optional array, queue row and float
    value must be finite, since a learner never holds NaN or inf there and one such value would spread
    through everything it computes after (a corrupt file is refused, not learned from)."""

    arrays: tuple[str, ...] = ()
    values: tuple[str, ...] = ()
    optional: tuple[str, ...] = ()
    members: Mapping[str, str] = field(default_factory=dict)
    queues: Mapping[str, Callable[[Any], tuple[int, ...]]] = field(default_factory=dict)
    nan_ok: tuple[str, ...] = ()

    def extend(self, arrays: tuple[str, ...] = (), values: tuple[str, ...] = (), optional: tuple[str, ...] = (),
               members: Mapping[str, str] | None = None,
               queues: Mapping[str, Callable[[Any], tuple[int, ...]]] | None = None,
               nan_ok: tuple[str, ...] = ()) -> Persist:
        """This declaration plus a subclass's fields."""
        return Persist(self.arrays + arrays, self.values + values, self.optional + optional,
                       {**self.members, **(members or {})}, {**self.queues, **(queues or {})},
                       self.nan_ok + nan_ok)


def key(attr: str) -> str:
    """The name an attribute is saved under: without its leading and trailing underscores."""
    return attr.strip("_")


def sub(arrays: Mapping[str, np.ndarray], name: str) -> Arrays:
    """The arrays of member `name` (prefix removed); all of them for the merged member ""."""
    if not name:
        return dict(arrays)
    prefix = f"{name}."
    return {k[len(prefix):]: v for k, v in arrays.items() if k.startswith(prefix)}


class Persistent:
    """A stateful object whose state is what its `PERSIST` declares (plus its hooks)."""

    __slots__ = ()
    PERSIST: ClassVar[Persist] = Persist()

    # --- hooks for what is not an attribute -------------------------------------------------------
    def _save_extra(self) -> tuple[Header, Arrays]:
        return {}, {}

    def _load_extra(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
        """Restore what `_save_extra` wrote (called after the declared fields are restored)."""

    # --- generic --------------------------------------------------------------------------------
    def _capture(self) -> tuple[Header, Arrays]:
        """(header, arrays) of the declared state, copied (the model may step on while they are written)."""
        decl = self.PERSIST
        header, arrays = self._save_extra()
        header.update({key(a): getattr(self, a) for a in decl.values})
        arrays.update({key(a): np.array(getattr(self, a)) for a in decl.arrays})
        arrays.update({key(a): np.array(getattr(self, a)) for a in decl.optional if getattr(self, a) is not None})
        for attr, row_shape in decl.queues.items():
            present, rows = stack_queue(getattr(self, attr), row_shape(self))
            header[f"{key(attr)}_present"], arrays[key(attr)] = present, rows
        for attr, name in decl.members.items():
            member = getattr(self, attr)
            if member is None:
                continue
            m_header, m_arrays = member._capture()
            _merge(header, {name: m_header} if name else m_header, attr)
            _merge(arrays, {f"{name}.{k}" if name else k: v for k, v in m_arrays.items()}, attr)
        return header, arrays

    def _restored(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray], where: str = "") -> Any:
        """This (freshly built) object holding the saved state; a class whose size is not fixed by its
        parameters returns a new object instead. `where`: the key prefix, for messages."""
        decl = self.PERSIST
        for a in decl.values:
            value = like(getattr(self, a), field_of(header, key(a), where), where + key(a))
            if isinstance(value, float) and a not in decl.nan_ok and not np.isfinite(value):
                raise LearningError(f"value {where + key(a)!r} is {value}: the file is corrupt")
            setattr(self, a, value)
        for a in decl.arrays:
            copy_into(getattr(self, a), arrays[key(a)], where + key(a))
            if a not in decl.nan_ok:
                require_finite(getattr(self, a), where + key(a))
        for a in decl.optional:
            optional = np.array(arrays[key(a)], dtype=float) if key(a) in arrays else None
            if optional is not None:
                require_finite(optional, where + key(a))
            setattr(self, a, optional)
        for attr, row_shape in decl.queues.items():
            present = field_of(header, f"{key(attr)}_present", where)
            fill_queue(getattr(self, attr), present, arrays[key(attr)], row_shape(self), where + key(attr))
        for attr, name in decl.members.items():
            member = getattr(self, attr)
            if member is not None:
                prefix = f"{where}{name}." if name else where
                saved = field_of(header, name, where) if name else header
                setattr(self, attr, member._restored(saved, sub(arrays, name), prefix))
        self._load_extra(header, arrays)
        return self


#: Every class whose checkpoint a wrapper can hold inside its own, by `kind`: a saved wrapper names the
#: kind of each model it wraps, and loading rebuilds that class from its parameters. A class enters on
#: definition (the first of a kind stays), so loading needs only its module imported.
_KINDS: dict[str, type[Checkpointed]] = {}


class Checkpointed(Persistent):
    """A top-level learner: its `kind`, its parameters (attribute `params`, of class `PARAMS`), its
    declared state; `save`/`load` write and read it as one checkpoint file."""

    __slots__ = ()
    kind: ClassVar[str]
    PARAMS: ClassVar[type]
    #: what a state that does not fit its class raises (the file's problem: LearningError)
    STATE_ERROR: ClassVar[type[GwrPredictorError]] = LearningError
    params: Any

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        kind = cls.__dict__.get("kind")
        if isinstance(kind, str):
            _KINDS.setdefault(kind, cls)

    @classmethod
    def _fresh(cls: type[_C], header: Mapping[str, Any]) -> _C:
        """A new object of the saved parameters, before its state is restored."""
        return cls(params_from_json(cls.PARAMS, header["params"]))  # type: ignore[call-arg]

    def _capture(self) -> tuple[Header, Arrays]:
        header, arrays = super()._capture()
        _merge(header, {"params": params_to_json(self.params)}, "params")
        return header, arrays

    def state(self) -> tuple[Header, Arrays]:
        """(JSON-able header, named arrays) of the whole state; `from_state` continues bit for bit."""
        return self._capture()

    @classmethod
    def from_state(cls: type[_C], header: Mapping[str, Any], arrays: Mapping[str, np.ndarray],
                   source: str | os.PathLike[str] = "<state>") -> _C:
        """The model of a `state()`; STATE_ERROR naming `source` and the field if anything does not fit
        the saved parameters (LearningError if arrays are missing)."""
        try:
            model = cls._fresh(header)
            expected = list(model._capture()[1])
        except (KeyError, ValueError, TypeError, IndexError, GwrPredictorError) as exc:
            cls._inconsistent(source, exc)
        require_arrays(expected, arrays, source)
        try:
            return model._restored(header, arrays)
        except (KeyError, ValueError, TypeError, IndexError, GwrPredictorError) as exc:
            cls._inconsistent(source, exc)

    @classmethod
    def _inconsistent(cls, source: str | os.PathLike[str], exc: Exception) -> NoReturn:
        raise_state_error(exc, source, "inconsistent checkpoint content", cls.STATE_ERROR)

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the whole state atomically (LearningError on failure)."""
        header, arrays = self.state()
        write_checkpoint(path, self.kind, header, arrays)

    @classmethod
    def load(cls: type[_C], path: str | os.PathLike[str]) -> _C:
        """A model saved by `save`, continuing where it stopped; LearningError naming the file otherwise."""
        header, arrays = read_checkpoint(path, cls.kind)
        return cls.from_state(header, arrays, path)


def kind_to_save(model: Any, what: str) -> str:
    """`model`'s kind if it can be saved inside a wrapper; LearningError naming `what` otherwise."""
    kind = getattr(model, "kind", None)
    if kind not in _KINDS or not isinstance(model, Checkpointed):
        raise LearningError(f"{what} ({type(model).__name__}) cannot be saved; supported: {', '.join(_KINDS)}")
    return str(kind)


def fresh_of_kind(kind: Any, header: Mapping[str, Any]) -> Checkpointed:
    """A fresh model of the saved `kind` and parameters (`header`), before its state is restored."""
    if not isinstance(kind, str) or kind not in _KINDS:
        raise LearningError(f"a wrapped model of kind {kind!r}; this build restores {', '.join(_KINDS)} "
                              "(a class restores once its module is imported)")
    return _KINDS[kind]._fresh(header)


# --- the pieces -------------------------------------------------------------------------------------
def params_to_json(params: Any) -> dict[str, Any]:
    """A parameters dataclass as JSON: its own `to_dict` / `to_flat` form if it has one."""
    for method in ("to_dict", "to_flat"):
        if callable(getattr(params, method, None)):
            return dict(getattr(params, method)())
    return dataclasses.asdict(params)


def params_from_json(cls: type, data: Any) -> Any:
    """Inverse of `params_to_json`; the class's own checks raise on bad values."""
    if not isinstance(data, dict):
        raise LearningError(f"params must be a JSON object, got {type(data).__name__}")
    for method in ("from_dict", "from_flat"):
        if callable(getattr(cls, method, None)):
            return getattr(cls, method)(data)
    return cls(**data)


def like(current: Any, value: Any, name: str) -> Any:
    """The saved `value` as the type the fresh object holds (`current`); LearningError naming it if not one."""
    if isinstance(current, dict):
        if not isinstance(value, dict) or value.keys() != current.keys():
            raise LearningError(f"value {name!r} must have the keys {sorted(current)}, got {value!r}"[:300])
        return {k: like(current[k], value[k], f"{name}.{k}") for k in current}
    numeric = (int, float, np.integer, np.floating)
    if isinstance(current, bool) or not isinstance(current, numeric):
        if type(value) is not type(current):
            raise LearningError(f"value {name!r} must be a {type(current).__name__}, got {value!r}"[:300])
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise LearningError(f"value {name!r} must be a number, got {value!r}"[:300])
    return type(current)(value)


def copy_into(dest: np.ndarray, src: np.ndarray, name: str) -> None:
    """`src` into `dest` (a checkpoint's array into the fresh learner's), or LearningError naming it."""
    src = np.asarray(src)
    if src.shape != dest.shape:
        raise LearningError(f"array {name!r} has shape {src.shape}, expected {dest.shape}")
    if not np.can_cast(src.dtype, dest.dtype, "same_kind"):
        raise LearningError(f"array {name!r} is {src.dtype}, expected {dest.dtype}")
    dest[...] = src


def require_finite(array: np.ndarray, name: str) -> None:
    """LearningError naming `name` if a float `array` holds NaN or inf."""
    if array.dtype.kind in "fc" and not np.isfinite(array).all():
        raise LearningError(f"array {name!r} holds non-finite values (NaN or inf): the file is corrupt")


def stack_queue(queue: deque[np.ndarray | None], row_shape: tuple[int, ...]) -> tuple[list[bool], np.ndarray]:
    """A queue of rows (None: absent) as (which are present, the rows stacked, zeros for the absent)."""
    rows = np.zeros((len(queue), *row_shape))
    for i, row in enumerate(queue):
        if row is not None:
            rows[i] = row
    return [row is not None for row in queue], rows


def fill_queue(queue: deque[np.ndarray | None], present: Any, rows: np.ndarray, row_shape: tuple[int, ...],
               name: str) -> None:
    """Append the saved rows to the (empty) queue; LearningError naming it if they do not fit."""
    rows = np.asarray(rows)
    if not isinstance(present, list) or not all(isinstance(p, bool) for p in present):
        raise LearningError(f"{name}_present must be a list of booleans")
    if rows.shape != (len(present), *row_shape) or (queue.maxlen is not None and len(present) > queue.maxlen):
        raise LearningError(f"queue {name!r} of shape {rows.shape} does not fit rows {row_shape} "
                            f"(at most {queue.maxlen}, {len(present)} flags)")
    if not np.can_cast(rows.dtype, float, "same_kind"):
        raise LearningError(f"queue {name!r} is {rows.dtype}, expected float")
    require_finite(rows[np.asarray(present, dtype=bool)], name)
    queue.extend(np.array(row, dtype=float) if flag else None for flag, row in zip(present, rows, strict=True))


def field_of(header: Mapping[str, Any], name: str, where: str) -> Any:
    """header[name], or LearningError naming the field (with its member's prefix) if it is not there."""
    if not isinstance(header, Mapping) or name not in header:
        raise LearningError(f"missing value {where + name!r}")
    return header[name]


def _merge(into: dict[str, Any], more: Mapping[str, Any], owner: str) -> None:
    clash = into.keys() & more.keys()
    if clash:
        raise LearningError(f"{owner}: names {sorted(clash)} are saved twice")
    into.update(more)
