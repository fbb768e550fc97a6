"""A growing memory of movement snippets, read out by the nearest ones at the present speed.

A person who repeats a movement passes the same poses in the same order, but never at the same speed
twice. The memory stores snippets: a key (the newest pose and its changes over the last 1, 2, 4 and
8 frames: `longest_lag`) and the `future` frames that followed it, as displacements from the key's
pose. A snippet is stored when no stored key lies within `insert_scale` x the running motion scale
of it (it grows when required, like the GWR). At `capacity` a new snippet replaces the one recalled
longest ago (stored, if never recalled), so a person met after hours still has their movements
learned; below it nothing is forgotten. On new motion nearly every frame is stored (the tracker's
noise keeps keys apart), so the default 5,000 snippets hold about ten minutes of motion that never
comes back, and what recurs is recalled and stays. A person holding a pose would add snippets for
ever the same way (a still key's changes are the tracker's noise): a still snippet (`still_radius`)
is stored only where no still one holds a pose that near. To
predict, the `k` nearest keys are read out at the present speed: a movement made r times as fast as
a stored one reaches the stored step k r at our step k, with r the least-squares ratio of the
present changes to the stored ones (clipped to [`min_ratio`, `max_ratio`]), read by linear
interpolation between stored frames. The neighbours are weighted by inverse squared distance. Where
the motion is familiar (`familiarity` at most `fit_radius`), `fit_k` neighbours are read out and their
futures fitted as a linear function of their keys' offsets from the present key (locally weighted ridge
regression), read at the present key: the performances stored around the present one (a little larger,
a little faster) are interpolated between instead of averaged, which on repeated real movements
anticipates better than the mean of the nearest (on the tuning set, research/tuning.md); elsewhere, the `k`
nearest are averaged, since a line fitted far from every neighbour extrapolates. A
stored key identical to the present one is skipped: a person never repeats a pose to the bit, so it
is the same recording replayed (a training epoch), and recalling it would score the memory as
perfect on data it has only copied.

`familiarity` says how well the memory knows the present motion: the distance to the nearest stored
key (copies aside), per coordinate, in units of the motion scale (None where it did not read out);
`travel` how far the pose has moved over the last `longest_lag` frames, in units of the motion scale
(near 0 while a person pauses, however well the pose is known).
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from gwr_predictor.default_predictor.errors import DefaultPredictorError
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.params import DEFAULT_HORIZON, MAX_HORIZON
from gwr_predictor.learning.persistence import Checkpointed, Persist, require_finite
from gwr_predictor.parameters.spec import ParamSpec, check_fields
from gwr_predictor.predictors.baselines import observation

#: The fewest frames stored after a key with `future` 0: the tuned default's at its horizon of 6 (where the
#: fastest read-out needs 10).
SHORTEST_FUTURE = 12
#: A key this close (squared, rad^2) to the present one is a copy of it: the same recording replayed.
EXACT = 1e-12
#: Above this many snippets a read first measures every key in float32 (half the bytes a search reads), then
#: the few it finds nearest exactly (`_near`); below it every key exactly.
FLOAT32_ABOVE = 2048

MEMORY_SPECS = {spec.name: spec for spec in (
    ParamSpec("horizon", DEFAULT_HORIZON, "frames predicted", 1, MAX_HORIZON),
    ParamSpec("n_joints", 8, "joints per frame", 1),
    ParamSpec("k", 3, "nearest snippets averaged where the motion is not familiar enough to fit", 1, 64),
    ParamSpec("fit_k", 32, "where the motion is familiar, this many nearest snippets fitted instead (0: never)", 0,
              256),
    ParamSpec("ridge", 0.35, "the fit's ridge, x the neighbours' mean key variance about their centroid", 0.0, 1e6,
              lo_open=True),
    ParamSpec("fit_radius", 3.0, "the motion is familiar enough to fit where `familiarity` is at most this", 0.0,
              1e3),
    ParamSpec("future", 0, "frames stored after each key (0: enough to read the fastest motion, horizon x max_ratio "
              f"rounded up, at least {SHORTEST_FUTURE})", 0, 4 * MAX_HORIZON),
    ParamSpec("longest_lag", 8, "the key holds the pose's changes over 1, 2, 4, ... frames up to this (a power of "
              "two)", 1, 64),
    ParamSpec("velocity_weight", 0.5, "weight of the key's changes against its pose in the distance", 0.0, 100.0),
    ParamSpec("insert_scale", 0.5, "a snippet is stored when no key is within this x the motion scale", 0.0, 1e3),
    ParamSpec("capacity", 5000, "snippets at most (there a new one replaces the one recalled longest ago)", 1,
              200_000),
    ParamSpec("still_radius", 2.0, "a snippet whose pose moves less than this x the motion scale over its key and its "
              "future is still, and is stored only where no still one's pose is that near (0: stored as any other)",
              0.0, 100.0),
    ParamSpec("min_ratio", 0.6, "slowest speed, against a stored snippet's, read out", 0.0, 1.0, lo_open=True),
    ParamSpec("max_ratio", 1.6, "fastest speed, against a stored snippet's, read out", 1.0, 10.0),
    ParamSpec("noise_floor", 0.01, "lower bound of the motion scale (rad)", 0.0, 10.0, lo_open=True),
    ParamSpec("motion_decay", 0.999, "forgetting of the motion scale per frame", 0.0, 1.0, lo_open=True,
              hi_open=True),
)}


@dataclass(frozen=True)
class MemoryParams:
    """Settings of `TrajectoryMemory` (see the module docstring and `MEMORY_SPECS`)."""

    SPECS: ClassVar[dict[str, ParamSpec]] = MEMORY_SPECS
    horizon: int = MEMORY_SPECS["horizon"].default
    n_joints: int = MEMORY_SPECS["n_joints"].default
    k: int = MEMORY_SPECS["k"].default
    fit_k: int = MEMORY_SPECS["fit_k"].default
    ridge: float = MEMORY_SPECS["ridge"].default
    fit_radius: float = MEMORY_SPECS["fit_radius"].default
    future: int = MEMORY_SPECS["future"].default
    longest_lag: int = MEMORY_SPECS["longest_lag"].default
    velocity_weight: float = MEMORY_SPECS["velocity_weight"].default
    insert_scale: float = MEMORY_SPECS["insert_scale"].default
    capacity: int = MEMORY_SPECS["capacity"].default
    still_radius: float = MEMORY_SPECS["still_radius"].default
    min_ratio: float = MEMORY_SPECS["min_ratio"].default
    max_ratio: float = MEMORY_SPECS["max_ratio"].default
    noise_floor: float = MEMORY_SPECS["noise_floor"].default
    motion_decay: float = MEMORY_SPECS["motion_decay"].default

    def __post_init__(self) -> None:
        check_fields(self, MEMORY_SPECS.values(), DefaultPredictorError)
        if self.future and self.future < self.horizon:
            raise DefaultPredictorError(f"MemoryParams.future {self.future} is shorter than the horizon "
                                        f"{self.horizon} (0 follows the horizon)")
        if self.longest_lag & (self.longest_lag - 1):
            raise DefaultPredictorError(f"MemoryParams.longest_lag {self.longest_lag} is not a power of two")
        if self.capacity < self.k:
            raise DefaultPredictorError(f"MemoryParams.capacity {self.capacity} is below k {self.k}")

    def replace(self, **changes: Any) -> MemoryParams:
        return dataclasses.replace(self, **changes)

    @property
    def stored_future(self) -> int:
        """Frames stored after each key: `future`, or with 0 what the fastest read-out of the horizon needs
        (a person's movement seen 6 frames ahead at 10 fps is 18 at 30 fps)."""
        # less a rounding hair: 25 x 2.2 is 55.00000000000001 in floats, and 55 frames read it
        return self.future or max(SHORTEST_FUTURE, math.ceil(self.horizon * self.max_ratio - 1e-9))

    @property
    def lags(self) -> tuple[int, ...]:
        """Frames back whose changes the key holds: 1, 2, 4, ... `longest_lag`."""
        return tuple(2 ** i for i in range(self.longest_lag.bit_length()))

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


class TrajectoryMemory(Checkpointed):
    """Online: stores each snippet once its future is observed (no peeking), predicts (horizon, J)
    from the snippets stored so far (None until it holds `k`). A missing sample (None/NaN) ends the
    present snippet; what is stored stays."""

    kind: ClassVar[str] = "TrajectoryMemory"
    PARAMS = MemoryParams
    PERSIST = Persist(values=("size", "_motion_ms", "clock", "replaced"),
                      queues={"_recent": lambda m: (m.params.n_joints,)})

    def __init__(self, params: MemoryParams | None = None) -> None:
        self.params = p = params or MemoryParams()
        self._lags = np.asarray(p.lags)
        self._span = p.longest_lag + 1
        self._key_weights = np.concatenate([np.ones(p.n_joints),
                                            np.full(len(self._lags) * p.n_joints, p.velocity_weight)])
        self._grid = np.arange(1, p.horizon + 1, dtype=float)
        self._future = p.stored_future  # the last stored step a read-out may reach
        self._needed = max(p.k, p.fit_k)  # the most neighbours a read takes
        self._few = 2 * self._needed + 16  # what a full memory's float32 pass hands on to be measured exactly
        # allocated once at capacity (the system maps the pages as snippets come): nothing grows while learning
        size = p.capacity
        self.keys = np.empty((size, len(self._key_weights)))  # pose, then its changes (unweighted)
        self._weighted = np.empty_like(self.keys)  # the keys x `_key_weights`, and their squared norms:
        self._norms = np.empty(size)  # a distance is then one matrix-vector product (`_distances`)
        self._weighted32 = np.empty(self.keys.shape, dtype=np.float32)  # the same in float32 (`_near`)
        self._norms32 = np.empty(size, dtype=np.float32)
        self.futures = np.empty((size, self._future + 1, p.n_joints))  # displacements from the key's pose, 0..future
        self.used = np.empty(size, dtype=np.int64)  # per snippet: the frame it was stored or last recalled at
        self.still = np.zeros(size, dtype=bool)  # per snippet: a still one (`still_radius`)
        # what a read leaves for the store of its own key `future` frames later (`_nearest_stored`): per read,
        # (clock, its key, the nearest squared distance, its slot); per store since, (clock, slot)
        self._reads: deque[tuple[int, np.ndarray, float, int]] = deque(maxlen=self._future + 1)
        self._stores: deque[tuple[int, int]] = deque(maxlen=self._future + 1)
        self.size = 0
        self.clock = 0  # frames observed (the clock of `used`)
        self.replaced = 0  # snippets replaced at capacity
        self._motion_ms = p.noise_floor ** 2  # running mean of ||x(t) - x(t-1)||^2
        self._recent: deque[np.ndarray] = deque(maxlen=self._span + self._future)
        self.familiarity: float | None = None
        self.travel: float | None = None

    def reset_sequence(self) -> None:
        self._recent.clear()
        self.familiarity = self.travel = None

    @property
    def motion_rms(self) -> float:
        return math.sqrt(self._motion_ms)

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        p = self.params
        obs = observation(x, p.n_joints)
        recent = self._recent
        self.familiarity = self.travel = None
        if obs is None:
            recent.clear()
            return None
        if recent:
            d = obs - recent[-1]
            self._motion_ms += (1.0 - p.motion_decay) * (float(d @ d) - self._motion_ms)
        recent.append(obs)
        self.clock += 1
        if len(recent) < self._span:
            return None
        frames = np.asarray(recent)  # oldest first: the snippet to store starts it, the present window ends it
        if learn and len(recent) == recent.maxlen:
            read = self._read_at(self.clock - self._future)  # the same window was read then: its key too
            key = self._key(frames[:self._span]) if read is None else read[1]
            self._store(key, frames[self._span - 1:] - frames[self._span - 1], read)
        if self.size < p.k:
            return None
        return obs + self._read(self._key(frames[-self._span:]))

    def _key(self, window: np.ndarray) -> np.ndarray:
        """The key of a (span, J) window, oldest first: its newest pose, then that pose minus each lagged one."""
        now = window[-1]
        return np.concatenate([now, (now - window[-1 - self._lags]).reshape(-1)])

    def _distances(self, query: tuple[np.ndarray, float], rows: np.ndarray | None = None) -> np.ndarray:
        """Weighted squared distances of the stored keys (all, or `rows`) to `key`, as |a|^2 - 2 a.b + |b|^2:
        one pass over the keys instead of three (the difference, its weighting, its norm), which is what a
        full memory's search costs. Rounding leaves ~1e-14 (rad^2) where the difference is 0: far below
        `EXACT`, far below any two keys of a recording. `query`: the key's `_query`."""
        b, bb = query
        if rows is None:
            weighted, norms = self._weighted[:self.size], self._norms[:self.size]
        else:
            weighted, norms = self._weighted.take(rows, axis=0), self._norms.take(rows)
        d2 = weighted @ b
        d2 *= -2.0
        d2 += norms
        d2 += bb
        return np.maximum(d2, 0.0, out=d2)

    def _query(self, key: np.ndarray) -> tuple[np.ndarray, float]:
        """The key weighted, and its squared norm: the b and |b|^2 of every distance to it."""
        b = key * self._key_weights
        return b, float(b @ b)

    def _read_at(self, clock: int) -> tuple[int, np.ndarray, float, int] | None:
        """What the read at `clock` left (None: none read then, or too long ago)."""
        reads = self._reads
        return reads[0] if reads and reads[0][0] == clock else next((r for r in reads if r[0] == clock), None)

    def _store(self, key: np.ndarray, future: np.ndarray, read: tuple[int, np.ndarray, float, int] | None) -> None:
        p = self.params
        still = p.still_radius > 0 and self._is_still(key, future)
        if self.size:
            if still:
                if self._near_still(key):
                    return
            else:
                radius = max(self.motion_rms, p.noise_floor) * p.insert_scale
                if self._nearest_stored(key, read) <= radius * radius * len(key) / p.n_joints:
                    return
        if self.size >= p.capacity:  # full: the snippet recalled longest ago makes room
            slot = int(np.argmin(self.used[:self.size]))
            self.replaced += 1
        else:
            slot = self.size
            self.size += 1
        self.keys[slot] = key
        self._weigh(slice(slot, slot + 1))
        self.futures[slot] = future
        self.used[slot] = self.clock
        self.still[slot] = still
        self._stores.append((self.clock, slot))

    def _is_still(self, key: np.ndarray, future: np.ndarray) -> bool:
        """Whether the pose moves less than `still_radius` x the motion scale over the key's longest lag and
        over every step of the future: a person holding a pose, whose key's changes are the tracker's noise."""
        p = self.params
        limit = (p.still_radius * max(self.motion_rms, p.noise_floor)) ** 2
        change = key[-p.n_joints:]
        return float(change.dot(change)) <= limit and float(np.einsum("fj,fj->f", future, future).max()) <= limit

    def _near_still(self, key: np.ndarray) -> bool:
        """Whether a stored still snippet's pose lies within `still_radius` x the motion scale of the key's.
        Poses only: a still key's changes are noise, which keeps keys of one held pose apart for ever."""
        p = self.params
        held = self.still[:self.size]
        if not held.any():
            return False
        diff = self.keys[:self.size, :p.n_joints] - key[:p.n_joints]
        d2 = np.einsum("nj,nj->n", diff, diff)
        return float(d2[held].min()) <= (p.still_radius * max(self.motion_rms, p.noise_floor)) ** 2

    def _nearest_stored(self, key: np.ndarray, read: tuple[int, np.ndarray, float, int] | None) -> float:
        """The squared distance of the nearest stored key to the key being stored, which the `read` of the
        same key `future` frames ago searched for already: its nearest then, unless that snippet was
        replaced since, against the few stored since (one search of a full memory per frame, not two)."""
        if read is None:
            return float(self._distances(self._query(key)).min())
        since = [slot for clock, slot in self._stores if clock > read[0]]
        if read[3] in since:  # the nearest then is gone
            return float(self._distances(self._query(key)).min())
        return min(read[2], float(self._distances(self._query(key), np.asarray(since)).min())) if since else read[2]

    def _weigh(self, rows: slice) -> None:
        """The weighted keys and their squared norms of stored `rows` (the same call stored or loaded, so a
        loaded memory continues to the bit)."""
        weighted = self._weighted[rows]
        np.multiply(self.keys[rows], self._key_weights, out=weighted)
        norms = np.einsum("nd,nd->n", weighted, weighted)
        self._norms[rows] = norms
        self._weighted32[rows] = weighted
        self._norms32[rows] = norms

    def _near(self, key: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(slots, exact squared distances to `key`) of every stored snippet a read may need: all of them, or in
        a memory above `FLOAT32_ABOVE` the few nearest by a float32 pass over all of them, measured again
        exactly. The float32 pass halves what a full memory's search reads; its rounding error is bounded
        (`bound`), so the few are used only where they surely hold the nearest ones a read needs and every
        copy; otherwise (near-ties at the cut) every key is measured exactly, as below the threshold."""
        if self.size <= FLOAT32_ABOVE:
            return np.arange(self.size), self._distances(self._query(key))
        needed, few = self._needed, self._few
        query, qq = searched = self._query(key)
        norms32 = self._norms32[:self.size]
        d32 = self._weighted32[:self.size] @ (query * -2.0).astype(np.float32)  # x -2 exactly: a power of two
        d32 += norms32
        d32 += np.float32(qq)
        slots = np.argpartition(d32, few - 1)[:few]
        slots.sort()  # in the slots' order, as the exact search of all returns them
        cut = float(d32[slots].max())
        # |float32 - exact| of |a|^2 - 2 a.b + |b|^2 over d values: every rounding at most 2^-24 relative, of
        # terms at most |a|^2 + |b|^2 (2 |a.b| <= |a|^2 + |b|^2), over 2 d + 4 of them; doubled
        bound = (4 * len(key) + 8) * 2.0 ** -24 * (float(norms32.max()) * (1 + 2.0 ** -23) + qq)
        d2 = self._distances(searched, slots)
        others = d2[d2 > EXACT]
        if len(others) >= needed and float(np.partition(others, needed - 1)[needed - 1]) < cut - bound:
            return slots, d2
        return np.arange(self.size), self._distances(searched)

    def _read(self, key: np.ndarray) -> np.ndarray:
        """(horizon, J) displacements: the k nearest snippets' futures at the present speed, weighted, or
        where the motion is familiar the `fit_k` nearest fitted (`_fit`)."""
        p = self.params
        slots, d2 = self._near(key)
        closest = int(d2.argmin())
        nearest_other, recallable = float(d2[closest]), self.size
        self._reads.append((self.clock, key, nearest_other, int(slots[closest])))
        if nearest_other <= EXACT:  # copies (a recording replayed): left out of the minimum, and of recall if
            copies = d2 <= EXACT  # enough others are left (`_near` holds every copy)
            masked = np.where(copies, np.inf, d2)
            others = self.size - int(np.count_nonzero(copies))
            nearest_other = float(masked.min())  # inf without others
            if others >= p.k:
                d2, recallable = masked, others  # a replayed recording is not recalled from its own copy
        scale = max(self.motion_rms, p.noise_floor)
        self.familiarity = math.sqrt(nearest_other * p.n_joints / len(key)) / scale
        change = key[-p.n_joints:]  # the key's change over the longest lag
        self.travel = math.sqrt(float(change.dot(change))) / scale
        fit = p.fit_k > 0 and self.familiarity <= p.fit_radius
        k = min(self._needed, recallable) if fit else p.k  # a fit takes the snippets there are
        chosen = np.argpartition(d2, k - 1)[:k] if len(d2) > k else np.arange(len(d2))
        if self.size > FLOAT32_ABOVE:  # in the slots' order (`_near`'s are ascending), however `_near` found them
            chosen.sort()
        nearest = slots[chosen]
        self.used[nearest] = self.clock
        w = d2[chosen]
        w += 1e-6
        np.divide(1.0, w, out=w)  # inverse squared distance
        w /= w.sum()
        keys = self.keys.take(nearest, axis=0)  # gathered once for the read-out and the fit
        read = self._at_present_speed(nearest, keys, key)
        if fit:
            keys -= key
            keys *= self._key_weights
            return self._fit(w, keys, read)
        return np.einsum("k,khj->hj", w, read)

    def _at_present_speed(self, nearest: np.ndarray, keys: np.ndarray, key: np.ndarray) -> np.ndarray:
        """(k, horizon, J): each snippet's future read at the present speed against its own (`keys`, theirs)."""
        p = self.params
        stored = keys[:, p.n_joints:]  # (k, lags * J) changes
        power = np.einsum("kd,kd->k", stored, stored)
        ratio = np.where(power > 1e-8, (stored @ key[p.n_joints:]) / np.maximum(power, 1e-8), 1.0)
        # clipped (finite: no stored or present angle beyond 100 rad), as np.clip does, in two cheaper calls
        np.minimum(np.maximum(ratio, p.min_ratio, out=ratio), p.max_ratio, out=ratio)
        at = np.minimum(ratio[:, None] * self._grid, self._future)  # (k, horizon) stored steps to read
        lo = at.astype(int)
        frac = (at - lo)[..., None]
        lo += nearest[:, None] * (self._future + 1)  # rows of the futures as one (snippets x steps, J) table
        hi = lo + (lo % (self._future + 1) < self._future)  # the next stored step, the last one's own
        table = self.futures.reshape(-1, self.futures.shape[2])
        return table.take(lo, axis=0) * (1.0 - frac) + table.take(hi, axis=0) * frac

    def _fit(self, w: np.ndarray, offsets: np.ndarray, read: np.ndarray) -> np.ndarray:
        """The neighbours' futures (k, horizon, J) as a linear function of their keys' (weighted) offsets
        from the present key, by weighted ridge regression, read at offset 0: neighbours on different sides
        of the present motion (another size, another speed) are interpolated between instead of averaged.
        Only where the motion is familiar: far from every neighbour the line would extrapolate.

        With X the neighbours' centred offsets (k, d), W their weights and lambda the ridge (`ridge` x the
        mean of diag(X'WX)), the fit's slope is (X'WX + lambda I)^-1 X'W Y, and only its value at the
        present key is needed: mean_y - mean_x (X'WX + lambda I)^-1 X'W Y, which by the push-through
        identity is mean_y - (W^1/2 u)' Y with (W^1/2 X X' W^1/2 + lambda I) u = W^1/2 X mean_x': one k x k
        system with one right-hand side instead of a d x d one with horizon x J."""
        futures = read.reshape(len(w), -1)
        mean_x, mean_y = w @ offsets, w @ futures
        x = offsets - mean_x
        root = np.sqrt(w)
        xs = x * root[:, None]
        gram = xs @ xs.T  # W^1/2 X X' W^1/2; its trace is X'WX's
        diagonal = gram.reshape(-1)[::len(w) + 1]  # a view
        diagonal += self.params.ridge * gram.trace() / x.shape[1] + 1e-12
        u = np.linalg.solve(gram, xs @ mean_x)
        u *= root
        futures = futures - mean_y
        return (mean_y - u @ futures).reshape(read.shape[1:])

    def errors(self) -> dict[str, Any]:
        return {"snippets": self.size, "snippets_replaced": self.replaced, "motion_rms_rad": self.motion_rms}

    # --- persistence: the stored snippets (as many as there are; the rest is declared above) ---------
    def _save_extra(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        n = self.size
        return {}, {"keys": self.keys[:n].copy(), "futures": self.futures[:n].copy(), "used": self.used[:n].copy(),
                    "still": self.still[:n].copy()}

    def _load_extra(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray]) -> None:
        n, p = self.size, self.params
        keys, futures = np.asarray(arrays["keys"]), np.asarray(arrays["futures"])
        if not 0 <= n <= p.capacity or keys.shape != (n, self.keys.shape[1]) or \
                futures.shape != (n, *self.futures.shape[1:]):
            raise LearningError(f"snippets of shapes {keys.shape}, {futures.shape} do not fit size {n} and the "
                                f"parameters (keys {self.keys.shape[1]}-d, futures {self.futures.shape[1:]})")
        require_finite(keys, "keys")
        require_finite(futures, "futures")
        self.keys[:n] = keys
        self.futures[:n] = futures
        self._weigh(slice(0, n))
        used, still = np.asarray(arrays["used"]), np.asarray(arrays["still"])
        if used.shape != (n,) or used.dtype.kind not in "iu" or (used < 0).any() or (used > self.clock).any():
            raise LearningError(f"snippet use times of shape {used.shape} do not fit size {n} and clock "
                                f"{self.clock}")
        self.used[:n] = used
        if still.shape != (n,) or still.dtype != bool:
            raise LearningError(f"snippet still flags of shape {still.shape} ({still.dtype}) do not fit size {n}")
        self.still[:n] = still
