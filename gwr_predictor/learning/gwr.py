"""Growing When Required network (Marsland et al. 2002; Sec. III-B of the paper), vectorised.

One `learn(x)` step, in this order (pinned down so that the firing-counter arithmetic is exact):

1. b, s = the two nearest neurons; activity a = exp(-c * ||x - w_b||) (Eq. 1; c = 1 unless the
   layer normalises distances).
2. Insert when a < a_T and h_b < f_T (h_b as it was *before* this step) and the size limit allows.
3. Without insertion, b and its neighbours move by eps * h * (x - w) with their current h (Eq. 4).
4. The edges of b age by one; the firing counters of b (rho_b) and of its neighbours (rho_n)
   decay by rho * kappa * (1 - h) - rho and are clipped to [0, 1] (Eq. 3), in both branches.
5. Topology: with insertion, r gets w_r = 0.5 (x + w_b) and h_r = 1, edge b-s is removed and
   edges r-b, r-s are created at age 0 (Eq. 2); otherwise edge b-s is created or refreshed to 0.
6. Edges of b older than max_edge_age are removed, then neurons left without any edge
   (swap-with-last compaction, highest index first).

At `max_neurons` (beyond the paper) the network keeps learning: an insertion first removes the neuron
that was best-matching longest ago (with its edges; never b, s or b's neighbours), so what recurs stays
and what never came back makes room. Edges age only at their BMU's end, so a neuron of motion that never
returns would otherwise stay for ever.

"Neighbours" are the neurons linked to b when the step starts. A fresh neuron (h = 1) is therefore
trained 8 times as BMU before it can cause an insertion: h after k firings is 0.7, 0.4945, ...,
0.1150 (k = 7), 0.0938 (k = 8) with rho_b = 0.3, kappa = 1.05.

Storage is chosen for ~1,000-5,000 neurons: weights in a contiguous matrix, allocated once at
`max_neurons` (doubling as it fills only when unbounded), whose last column holds each neuron's
squared norm, kept up to date on every change, so the BMU search is one BLAS matrix-vector product
[w | ||w||^2] . [x | -1/2] = w.x - ||w||^2 / 2 followed by an argmax (the nearest neuron maximises
it; ||x||^2 is common to all), all of it in one internal searcher (`_Search`: BMU and second BMU, the
kept product), so `learn` reads as the steps above. Edges live in an `EdgeTable` (a few slots per
neuron, `edges.py`): memory and each step linear in n at most. b and its neighbours are updated
together as one small gathered block. Only the first `match_dim` values of a vector are matched; the
rest are carried in a second matrix (the Predictive GWR's output weights), so the matched block
stays contiguous for BLAS.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, NamedTuple, TypeVar

import numpy as np

from gwr_predictor.learning.edges import EdgeTable
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.params import MAX_EDGE_AGE_LIMIT, GWRParams
from gwr_predictor.learning.persistence import Persistent

_G = TypeVar("_G", bound="GWR")

_MIN_CAPACITY = 64
#: `_matched` of a neuron that may not be evicted now
_KEEP = np.iinfo(np.int64).max


def counter_decay(rho: float, kappa: float) -> tuple[float, float]:
    """(a, c) such that h + rho * kappa * (1 - h) - rho == h * a + c (Eq. 3)."""
    return 1.0 - rho * kappa, rho * kappa - rho


class _Search:
    """The nearest-neuron search of one network: BMU and second BMU of a query over the first n rows
    of [w | ||w||^2], by one BLAS product with [x | -1/2] and an argmax (see the module docstring).

    It keeps one result: `affinity(xm, n, keep=True)` computes into a second buffer that the next
    `two_nearest` of the same query bytes reuses, as long as the network did not change in between
    (learning calls `two_nearest`, which drops it). Recursive mode forecasts from r(t), then learns
    (r(t), x(t+1)) next frame with the P-GWR unchanged in between: one 73-d product less per frame.
    """

    __slots__ = ("buf", "kept", "kept_buf", "wa", "xa")

    def __init__(self, wa: np.ndarray) -> None:
        cap, m1 = wa.shape
        self.wa = wa
        self.xa = np.empty(m1)  # [query | -1/2]
        self.xa[-1] = -0.5
        self.buf = np.empty(cap)
        self.kept_buf = np.empty(cap)
        self.kept: bytes | None = None  # the query whose affinity `kept_buf` holds

    def affinity(self, xm: np.ndarray, n: int, keep: bool = False) -> np.ndarray:
        """w.x - ||w||^2 / 2 of the first n neurons, largest for the nearest (one product)."""
        xa = self.xa
        xa[:-1] = xm
        out = (self.kept_buf if keep else self.buf)[:n]
        np.dot(self.wa[:n], xa, out=out)
        if keep:
            self.kept = xm.tobytes()
        return out

    def two_nearest(self, xm: np.ndarray, n: int) -> tuple[int, int]:
        """(b, s): the nearest and second-nearest neuron of xm (a kept affinity is used and dropped)."""
        if self.kept is not None and self.kept == xm.tobytes():
            aff = self.kept_buf[:n]
        else:  # `affinity`, inlined (a call less per learning step)
            xa = self.xa
            xa[:-1] = xm
            aff = self.buf[:n]
            np.dot(self.wa[:n], xa, out=aff)
        self.kept = None
        b = int(aff.argmax())
        aff[b] = -np.inf
        return b, int(aff.argmax())

    def nearest(self, xm: np.ndarray, n: int) -> int:
        return int(self.affinity(xm, n).argmax())



class Prepared(NamedTuple):
    """What a caller has just computed for one query on a network, handed to its learning step so that
    nothing is computed twice: the BMU b, b's neighbours (ascending) and their slots in b's edge row,
    ||x - w_b||^2 and, for a subclass that scales its neurons' rates, the factors (None: full rates) it
    found for a block of `scaled` neurons starting with b (0: none found; the block [b, neighbours...]
    if `scaled` is its size)."""

    b: int
    neighbours: np.ndarray
    slots: np.ndarray
    dist2: float
    rate_scale: np.ndarray | None = None
    scaled: int = 0
    #: for the block [b, neighbours...]: its gathered rows of [w | ||w||^2], x - w, its gathered carried
    #: weights and x_carried - w_carried (None: not gathered), which the step updates in place
    gathered: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None

class GWR(Persistent):
    """A GWR network over `dim`-dimensional vectors; see the module docstring for the step."""

    # the storage `_alloc` (re)builds: [w | ||w||^2], carried weights, firing counters, edges, and the
    # learning step at which each neuron was last the BMU (or inserted): what eviction reads
    _wa: np.ndarray
    _wo: np.ndarray
    _h: np.ndarray
    _edges: EdgeTable
    _matched: np.ndarray
    #: learning steps taken (the clock of `_matched`)
    clock: int = 0
    #: neurons removed at `max_neurons` to make room for a new one
    evicted: int = 0

    def __init__(self, dim: int, params: GWRParams, rng: np.random.Generator, *,
                 match_dim: int | None = None, init_low: float | np.ndarray = -1.0,
                 init_high: float | np.ndarray = 1.0, distance_factor: float = 1.0) -> None:
        self._setup(int(dim), params, match_dim, distance_factor, capacity=_MIN_CAPACITY)
        self._put(np.arange(2), rng.uniform(init_low, init_high, size=(2, self.dim)))
        self._h[:2] = 1.0
        self._n = 2

    # --- construction helpers -------------------------------------------------------------------
    def _setup(self, dim: int, params: GWRParams, match_dim: int | None, distance_factor: float,
               capacity: int, needed: int = 2) -> None:
        if not isinstance(params, GWRParams):
            raise TypeError(f"params must be GWRParams, got {type(params).__name__}")
        if dim < 1:
            raise LearningError(f"GWR dim must be >= 1, got {dim}")
        match_dim = dim if match_dim is None else int(match_dim)
        if not 1 <= match_dim <= dim:
            raise LearningError(f"GWR match_dim must be in [1, {dim}], got {match_dim}")
        if not (math.isfinite(distance_factor) and distance_factor > 0):
            raise LearningError(f"GWR distance_factor must be > 0, got {distance_factor!r}")
        self.dim = dim
        self.match_dim = match_dim
        self.params = params
        self.distance_factor = float(distance_factor)
        #: Index of the neuron inserted by the last `learn` (-1: none).
        self.last_inserted = -1
        #: Euclidean distance between the last input and its BMU (matched part).
        self.last_distance = math.nan
        # per-row constants of the gathered block [b, neighbours...]; Eq. 3 as h <- h * a + c with
        # a = 1 - rho * kappa, c = rho * kappa - rho (the same update, two operations)
        self._rates = (params.eps_b, params.eps_n)
        self._decay = (counter_decay(params.rho_b, params.kappa), counter_decay(params.rho_n, params.kappa))
        # With rho * kappa <= 1, h * a + c maps [0, 1] into [0, 1] even in floating point (a >= 0,
        # c >= 0, a + c = 1 - rho): the clip of Eq. 3 is then a no-op and skipped.
        self._clip_counters = max(params.rho_b, params.rho_n) * params.kappa > 1.0
        self._n = 0
        self._alloc(self._capacity_for(capacity, needed))

    def _capacity_for(self, preferred: int, needed: int) -> int:
        """max_neurons rows when bounded (allocated once: no reallocation while learning); unbounded,
        `preferred` rows (at least the minimum), never below `needed`."""
        limit = self.params.max_neurons
        return max(max(_MIN_CAPACITY, preferred) if limit is None else limit, needed)

    def _alloc(self, cap: int) -> None:
        """(Re)allocate the arrays with room for `cap` neurons, keeping the first n."""
        n, m = self._n, self.match_dim
        old = getattr(self, "_wa", None)
        # [w | ||w||^2]: one product with [x | -1/2] gives w.x - ||w||^2 / 2 for every neuron, whose
        # maximum is the BMU (||x - w||^2 = ||x||^2 - 2 (w.x - ||w||^2 / 2))
        wa = np.zeros((cap, m + 1))
        wo = np.zeros((cap, self.dim - m))
        h = np.zeros(cap)
        matched = np.zeros(cap, dtype=np.int64)
        if old is not None and n:
            wa[:n], wo[:n], h[:n], matched[:n] = self._wa[:n], self._wo[:n], self._h[:n], self._matched[:n]
            self._edges = self._edges.grown(cap, n)
        else:
            self._edges = EdgeTable(cap)
        self._wa, self._wo, self._h, self._matched = wa, wo, h, matched
        self._search = _Search(wa)
        # per-row rate/decay vectors of the block [b, neighbours...], longest possible block
        block = self._edges.degree + 1
        self._eps_vec = np.full(block, self._rates[1])
        self._eps_vec[0] = self._rates[0]
        self._decay_a = np.full(block, self._decay[1][0])
        self._decay_a[0] = self._decay[0][0]
        self._decay_c = np.full(block, self._decay[1][1])
        self._decay_c[0] = self._decay[0][1]
        self._block = np.empty(block, dtype=np.intp)

    @property
    def _w(self) -> np.ndarray:
        """The matched weights: a strided view of [w | ||w||^2], taken on each use (a stored view would
        not follow a deep copy, which copies it apart from the array it views)."""
        return self._wa[:, :self.match_dim]

    def _put(self, idx: np.ndarray | int, rows: np.ndarray) -> None:
        """Write whole weight rows (matched + carried part) and refresh their norms."""
        rows = np.asarray(rows, dtype=float)
        m = self.match_dim
        self._w[idx] = rows[..., :m]
        self._wo[idx] = rows[..., m:]
        wm = self._w[idx]
        self._wa[idx, m] = np.vecdot(wm, wm)

    @classmethod
    def from_arrays(cls: type[_G], weights: np.ndarray, params: GWRParams, *, edges: Any = (),
                    counters: np.ndarray | None = None, match_dim: int | None = None,
                    distance_factor: float = 1.0) -> _G:
        """A network with given neurons and edges ((i, j, age) triples): hand-made cases, pre-grown
        benchmark networks and checkpoints."""
        weights = np.array(weights, dtype=float, ndmin=2)
        n, dim = weights.shape
        if n < 2:
            raise LearningError(f"a GWR needs at least 2 neurons, got {n}")
        if params.max_neurons is not None and n > params.max_neurons:
            raise LearningError(f"{n} neurons exceed max_neurons={params.max_neurons}")
        if not np.isfinite(weights).all():
            raise LearningError("weights contain NaN or infinite values")
        net = cls.__new__(cls)
        net._setup(dim, params, match_dim, distance_factor, capacity=n, needed=n)
        net._put(np.arange(n), weights)
        h = np.ones(n) if counters is None else np.asarray(counters, dtype=float)
        if h.shape != (n,) or not ((h >= 0) & (h <= 1)).all():
            raise LearningError(f"counters must be {n} values in [0, 1]")
        net._h[:n] = h
        net._n = n
        edges = np.asarray(edges, dtype=np.int64).reshape(-1, 3)
        if edges.size:
            i, j, a = edges.T
            if (i < 0).any() or (j < 0).any() or (i >= n).any() or (j >= n).any() or (i == j).any():
                raise LearningError(f"edges must join two distinct neurons in [0, {n}), got {edges.tolist()[:5]}")
            if (a < 0).any() or (a > MAX_EDGE_AGE_LIMIT + 1).any():  # int16 storage with room to age
                raise LearningError(f"edge ages must be in [0, {MAX_EDGE_AGE_LIMIT + 1}]")
            net._edges.fill(edges)
        return net

    def _restore_clock(self, matched: np.ndarray, clock: int) -> None:
        """Eviction's record from a checkpoint: when each neuron was last the BMU, on a clock at `clock`."""
        n = self._n
        matched = np.asarray(matched)
        if matched.shape != (n,) or matched.dtype.kind not in "iu" or (matched < 0).any() or (matched > clock).any():
            raise LearningError(f"last-matched steps must be {n} whole numbers in [0, clock {clock}]")
        self._matched[:n] = matched
        self.clock = int(clock)

    # --- read-only views ------------------------------------------------------------------------
    @property
    def n_neurons(self) -> int:
        return self._n

    @property
    def capacity(self) -> int:
        """Neurons the arrays have room for (max_neurons when bounded; doubles when full otherwise)."""
        return self._h.shape[0]

    @property
    def weights(self) -> np.ndarray:
        """(n, dim) weights: a view when every value is matched, else a copy. Do not write to it."""
        if self.match_dim == self.dim:
            return self._w[:self._n]
        return np.concatenate([self._w[:self._n], self._wo[:self._n]], axis=1)

    @property
    def counters(self) -> np.ndarray:
        """(n,) view of the firing counters h."""
        return self._h[:self._n]

    @property
    def last_matched(self) -> np.ndarray:
        """(n,) view of the learning step (`clock`) at which each neuron was last the BMU or inserted."""
        return self._matched[:self._n]

    def edge_array(self) -> np.ndarray:
        """(E, 3) int64 array of edges (i, j, age) with i < j, in row-major order."""
        return self._edges.edge_array(self._n)

    def neighbours(self, i: int) -> np.ndarray:
        """Neighbours of neuron i, ascending."""
        return self._edges.neighbours(i)[0]

    def neighbour_slots(self, b: int) -> tuple[np.ndarray, np.ndarray]:
        """(b's neighbours ascending, their slots in b's edge row): what `Prepared` carries."""
        return self._edges.neighbours(b)

    def edge_age(self, i: int, j: int) -> int | None:
        """Age of edge i-j, or None when there is none."""
        return self._edges.age(i, j)

    # --- matching -------------------------------------------------------------------------------
    def _check_input(self, x: Any, size: int) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.shape != (size,):
            raise LearningError(f"expected a vector of shape ({size},), got {x.shape}")
        if not math.isfinite(x.sum()):
            raise LearningError("input contains NaN or infinite values")
        return x

    def _distance(self, i: int, xm: np.ndarray) -> float:
        diff = xm - self._w[i]
        return math.sqrt(float(np.dot(diff, diff)))

    def nearest(self, xm: np.ndarray) -> int:
        """Index of the BMU of a matched-part vector (trusted input: no checks, no state change)."""
        return self._search.nearest(xm, self._n)

    def bmu(self, x: np.ndarray) -> tuple[int, float]:
        """(index, Euclidean distance) of the BMU of x, given whole or as its matched part. No learning."""
        xm = self._check_input(x, self.dim if np.shape(x) == (self.dim,) else self.match_dim)[:self.match_dim]
        b = self._search.nearest(xm, self._n)
        dist = self._distance(b, xm)
        self.last_distance = dist
        return b, dist

    def search_views(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(A, xa, buf, w) for inlined read-only BMU searches in hot loops: write the query into
        xa[:-1], `np.dot(A, xa, out=buf)`, and buf.argmax() is the BMU, w its matched weights.
        Valid only until the network next changes (learning may reallocate or resize)."""
        n, search = self._n, self._search
        return search.wa[:n], search.xa, search.buf[:n], self._w

    def search_keep(self, xm: np.ndarray) -> np.ndarray:
        """The affinity of a trusted matched-part vector, kept for the next learning step on the same
        query if the network does not change before it (`_Search`)."""
        return self._search.affinity(xm, self._n, keep=True)

    def match_unchecked(self, xm: np.ndarray) -> int:
        """BMU index of a trusted matched-part vector; records `last_distance`. No learning."""
        b = self._search.nearest(xm, self._n)
        self.last_distance = self._distance(b, xm)
        return b

    def weight_row(self, i: int) -> np.ndarray:
        """View of neuron i's matched weights (valid until the network changes)."""
        return self._w[i]

    def activity(self, x: np.ndarray) -> float:
        """Eq. 1: exp(-c ||x - w_b||) for the BMU b of x."""
        return math.exp(-self.distance_factor * self.bmu(x)[1])

    # --- learning -------------------------------------------------------------------------------
    def learn(self, x: np.ndarray) -> int:
        """One GWR step on x (shape (dim,)); returns the final index of the BMU."""
        return self.learn_unchecked(self._check_input(x, self.dim))

    def learn_unchecked(self, x: np.ndarray, carried: np.ndarray | None = None,
                        neighbours: Prepared | None = None) -> int:
        """`learn` on trusted finite float vectors: x whole (dim,), or x its matched part and
        `carried` the rest (a Predictive GWR's (x_in, x_out): no concatenated copy). `neighbours`:
        what the caller has just computed for this very query on this network (used only if b is
        again the BMU), so none of it is computed twice."""
        p = self.params
        n = self._n
        m = self.match_dim
        xm, xc = (x[:m], x[m:]) if carried is None else (x, carried)
        b, s = self._search.two_nearest(xm, n)  # 1. the two nearest neurons
        known = neighbours if neighbours is not None and neighbours[0] == b else None
        dist = math.sqrt(known[3]) if known is not None else self._distance(b, xm)
        self.last_distance = dist
        self.clock += 1

        edges = self._edges
        nb, slots = (known[1], known[2]) if known is not None else edges.neighbours(b)
        k = nb.size + 1
        block = self._block[:k]  # [b, neighbours...]
        block[0] = b
        block[1:] = nb
        h = self._h.take(block)
        hb = float(h[0])
        insert = math.exp(-self.distance_factor * dist) < p.activation_threshold and hb < p.firing_threshold
        victim = -1
        if insert and p.max_neurons is not None and n >= p.max_neurons:  # full: who makes room (if anyone may)
            victim = self._victim(block, s)
            insert = victim >= 0
        if not insert:  # Eq. 4 on b and its neighbours at once
            rate = self._step_rates(block, h, known)
            given = known.gathered if known is not None else None
            if given is not None and given[0].shape[0] != k:
                given = None  # gathered for another block
            wa = self._wa.take(block, axis=0) if given is None else given[0]
            w = wa[:, :m]
            if m < self.dim:  # the carried part (Eq. 9), the same rates
                if given is None:
                    wo = self._wo.take(block, axis=0)
                    carried_step = xc - wo
                else:
                    wo, carried_step = given[2], given[3]
                carried_step *= rate
                wo += carried_step
                self._wo[block] = wo
            step = xm - w if given is None else given[1]
            step *= rate  # w += rate * (x - w), with one temporary fewer (same products)
            w += step
            wa[:, m] = np.vecdot(w, w)
            self._wa[block] = wa
        # ageing of b's edges and firing counters (Eq. 3), in both branches
        if k > 1:
            ages = edges.grow_older(b, nb, slots)
        h *= self._decay_a[:k]
        h += self._decay_c[:k]
        if self._clip_counters:
            np.minimum(np.maximum(h, 0.0, out=h), 1.0, out=h)
        self._h[block] = h
        # topology
        r = -1
        if insert:  # Eq. 2
            if victim >= 0:
                moved = self._evict(victim)
                b, s = (victim if b == moved else b), (victim if s == moved else s)
                nb = np.where(nb == moved, victim, nb)
            r = self._append(xm, xc, b)
            edges = self._edges  # may have been reallocated
            edges.unlink(b, s)
            edges.link(r, b)
            edges.link(r, s)
            self._matched[r] = self.clock
        else:
            edges.link(b, s)
        if k > 1 and max(ages.tolist()) > p.max_edge_age:
            old = nb[(ages > p.max_edge_age) & (nb != s)]
            if old.size:
                b, r = self._drop_edges(b, old, r)
        self._matched[b] = self.clock
        self.last_inserted = r
        return b

    def _victim(self, keep: np.ndarray, also: int) -> int:
        """The neuron best-matching longest ago outside `keep` and `also` (-1: every neuron is kept)."""
        matched = self._matched[:self._n].copy()
        matched[keep] = _KEEP
        matched[also] = _KEEP
        v = int(matched.argmin())
        return -1 if matched[v] == _KEEP else v

    def _evict(self, victim: int) -> int:
        """Remove `victim` and its edges to make room; returns the old index of the neuron moved into its slot."""
        self._edges.unlink_all(victim)
        self.evicted += 1
        return self._remove(victim)

    def _step_rates(self, block: np.ndarray, h: np.ndarray, prepared: Prepared | None = None) -> np.ndarray:
        """(k, 1) rates of Eq. 4 (and 9) for the block [b, neighbours...] with firing counters h:
        eps_b h_b, eps_n h_n. A subclass may scale them (`LocalLinearPGWR` consolidates its neurons),
        with what its caller `prepared` for this very block (None: nothing)."""
        return (self._eps_vec[:block.size] * h)[:, None]

    # --- structure changes ----------------------------------------------------------------------
    def _append(self, xm: np.ndarray, xc: np.ndarray, b: int) -> int:
        """New neuron at 0.5 (x + w_b) with h = 1 (x as matched and carried part); returns its index."""
        if self._n == self._w.shape[0]:
            self._alloc(self._capacity_for(2 * self._n, self._n + 1))
        r = self._n
        m = self.match_dim
        w = 0.5 * (xm + self._w[b])
        self._w[r] = w
        self._wo[r] = 0.5 * (xc + self._wo[b])
        self._wa[r, m] = w @ w
        self._h[r] = 1.0
        self._n = r + 1
        return r

    def _drop_edges(self, b: int, old: np.ndarray, r: int) -> tuple[int, int]:
        """Remove edges b-old, then the `old` neurons left isolated; returns b and r re-indexed."""
        edges = self._edges
        for i in old.tolist():  # a handful of edges, not a loop over the network
            edges.unlink(b, i)
        for i in np.sort(old)[::-1].tolist():
            if edges.has_edges(i):
                continue
            moved = self._remove(i)
            b = i if b == moved else b
            r = i if r == moved else r
        return b, r

    def _remove(self, i: int) -> int:
        """Delete isolated neuron i by moving the last neuron into its slot; returns the old index
        of the moved neuron (== i when i was last)."""
        last = self._n - 1
        if i != last:
            for arr in (self._wa, self._wo, self._h, self._matched):
                arr[i] = arr[last]
            self._edges.move(last, i)
        self._n = last
        return last

    # --- persistence ----------------------------------------------------------------------------
    #: The array members of `state()`; the others are plain JSON-able values.
    STATE_ARRAYS = ("weights", "counters", "edges", "last_matched")

    def state(self) -> dict[str, Any]:
        """Arrays and plain values that reproduce this network exactly (see `from_state`); the one
        persistence format of a network, used by every checkpoint that holds one."""
        return {
            "weights": self.weights.copy(),
            "counters": self.counters.copy(),
            "edges": self.edge_array(),
            "last_matched": self.last_matched.copy(),
            "clock": self.clock,
            "evicted": self.evicted,
            "match_dim": self.match_dim,
            "distance_factor": self.distance_factor,
            "params": dataclasses.asdict(self.params),
        }

    @classmethod
    def from_state(cls, state: dict[str, Any]) -> GWR:
        params = GWRParams(**state["params"])
        net = cls.from_arrays(state["weights"], params, edges=state["edges"], counters=state["counters"],
                              match_dim=int(state["match_dim"]), distance_factor=float(state["distance_factor"]))
        net._restore_clock(state["last_matched"], int(state["clock"]))
        net.evicted = int(state["evicted"])
        return net

    def _capture(self) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """A network as a checkpoint member: `state`, its arrays apart."""
        state = self.state()
        return state, {a: state.pop(a) for a in self.STATE_ARRAYS}

    def _restored(self, header: Mapping[str, Any], arrays: Mapping[str, np.ndarray], where: str = "") -> GWR:
        """The saved network in place of this one (built from the owner's parameters), which it must
        match in size, matching part, distance factor and parameters (a network's size is not fixed)."""
        net = type(self).from_state({**header, **{a: arrays[a] for a in self.STATE_ARRAYS}})
        for what in ("dim", "match_dim", "distance_factor", "params"):
            if getattr(net, what) != getattr(self, what):
                raise LearningError(f"layer {where.rstrip('.')} has {what} {getattr(net, what)!r}, "
                                    f"the parameters say {getattr(self, what)!r}")
        return net
