"""A GWR's edges: per neuron a fixed number of (neighbour, age) slots instead of an n x n matrix.

A GWR neuron has a handful of neighbours (at most 16 in the default's network and 44 in the paper's
GWR2 over the demonstrator and an hour of new motion), so a dense age matrix spends n^2 memory on
empty cells and has to be copied whole when the network grows. Here each neuron owns `degree` slots:
memory and every operation are linear in n (most are constant), and a network can be allocated once
at its bound. Each edge is kept in both of its neurons' rows with the same age.

When a neuron whose slots are all taken gains an edge, its oldest edge gives way (both ends), as
ageing would remove it first anyway; below `degree` edges per neuron the edges are exactly those of
the dense matrix.
"""

from __future__ import annotations

import numpy as np

#: Edges per neuron before the oldest gives way (above every degree measured, see the module docstring).
DEGREE = 64


class EdgeTable:
    """Symmetric edge ages of up to `capacity` neurons, `degree` slots each.

    A slot holds its neighbour's index + 1 (0: empty), so a new table is all zeros: memory the system
    maps only as neurons come, whatever the capacity."""

    __slots__ = ("ages", "degree", "ids")

    def __init__(self, capacity: int, degree: int = DEGREE) -> None:
        self.degree = degree
        self.ids = np.zeros((capacity, degree), dtype=np.int32)  # neighbour + 1 per slot
        self.ages = np.zeros((capacity, degree), dtype=np.int16)  # its edge's age

    def grown(self, capacity: int, n: int) -> EdgeTable:
        """A table with room for `capacity` neurons holding this one's first n rows."""
        out = EdgeTable(capacity, self.degree)
        out.ids[:n] = self.ids[:n]
        out.ages[:n] = self.ages[:n]
        return out

    def neighbours(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """(neighbours of i in ascending order, their slots in i's row)."""
        row = self.ids[i]
        slots = row.nonzero()[0]
        ids = row[slots] - 1
        if ids.size > 1:
            order = ids.argsort()
            return ids[order], slots[order]
        return ids, slots

    def has_edges(self, i: int) -> bool:
        return bool(self.ids[i].any())

    def _slot(self, i: int, j: int) -> int:
        """The slot of neighbour j in i's row (-1: none)."""
        hit = (self.ids[i] == j + 1).nonzero()[0]
        return int(hit[0]) if hit.size else -1

    def age(self, i: int, j: int) -> int | None:
        """Age of edge i-j, None without one."""
        slot = self._slot(i, j)
        return None if slot < 0 else int(self.ages[i, slot])

    def grow_older(self, b: int, ids: np.ndarray, slots: np.ndarray) -> np.ndarray:
        """Age every edge of b by one (b's neighbours `ids` in its `slots`); returns the new ages."""
        ages = self.ages[b, slots] + 1
        self.ages[b, slots] = ages
        back = (self.ids[ids] == b + 1).argmax(axis=1)  # b's slot in each neighbour's row
        self.ages[ids, back] = ages
        return ages

    def link(self, i: int, j: int) -> None:
        """Create edge i-j at age 0, or refresh it to 0."""
        self._half_link(i, j)
        self._half_link(j, i)

    def _half_link(self, i: int, j: int) -> None:
        row = self.ids[i]
        slot = self._slot(i, j)
        if slot >= 0:
            self.ages[i, slot] = 0
            return
        free = (row == 0).nonzero()[0]
        if free.size:
            slot = int(free[0])
        else:  # full: the oldest edge gives way, at both its ends
            slot = int(self.ages[i].argmax())
            self._drop_half(int(row[slot]) - 1, i)
        row[slot] = j + 1
        self.ages[i, slot] = 0

    def unlink(self, i: int, j: int) -> None:
        """Remove edge i-j if there is one."""
        self._drop_half(i, j)
        self._drop_half(j, i)

    def _drop_half(self, i: int, j: int) -> None:
        slot = self._slot(i, j)
        if slot >= 0:
            self.ids[i, slot] = 0

    def unlink_all(self, i: int) -> None:
        """Remove every edge of i."""
        row = self.ids[i]
        nb = row[row > 0] - 1
        if nb.size:
            hit = (self.ids[nb] == i + 1).argmax(axis=1)
            self.ids[nb, hit] = 0
        row[:] = 0

    def move(self, src: int, dst: int) -> None:
        """Neuron `src` takes slot `dst` (which has no edges): its row moves, and its neighbours now name `dst`."""
        row = self.ids[src]
        nb = row[row > 0] - 1
        if nb.size:
            hit = (self.ids[nb] == src + 1).argmax(axis=1)
            self.ids[nb, hit] = dst + 1
        self.ids[dst] = row
        self.ages[dst] = self.ages[src]
        row[:] = 0

    def edge_array(self, n: int) -> np.ndarray:
        """(E, 3) int64 array of edges (i, j, age) with i < j, in row-major order."""
        ids = self.ids[:n].astype(np.int64) - 1
        rows = np.broadcast_to(np.arange(n)[:, None], ids.shape)
        keep = ids > rows
        i, j, a = rows[keep], ids[keep], self.ages[:n][keep]
        order = np.lexsort((j, i))
        return np.stack([i[order], j[order], a[order]], axis=1).astype(np.int64)

    def fill(self, edges: np.ndarray) -> None:
        """Set the edges (i, j, age) of a fresh table (checked by the caller): each edge in the next free slot
        of both its rows; beyond `degree` edges per neuron (or for an edge given twice) one at a time, the
        oldest giving way."""
        both = np.concatenate([edges, edges[:, [1, 0, 2]]])  # (2E, 3): row, neighbour, age
        both = both[np.lexsort((both[:, 1], both[:, 0]))]
        rows, nbrs = both[:, 0], both[:, 1]
        rank = np.arange(len(both)) - np.searchsorted(rows, rows)  # the slot within its row
        repeated = ((rows[1:] == rows[:-1]) & (nbrs[1:] == nbrs[:-1])).any()
        if not len(both) or (rank.max() < self.degree and not repeated):
            self.ids[rows, rank] = nbrs + 1
            self.ages[rows, rank] = both[:, 2]
            return
        for i, j, a in edges.tolist():
            self.link(i, j)
            self.ages[i, self._slot(i, j)] = a
            self.ages[j, self._slot(j, i)] = a
