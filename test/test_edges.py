"""A GWR's edge table: slots per neuron, both ends kept alike, the oldest edge giving way when full."""

import subprocess
import sys

import numpy as np

from gwr_predictor.learning.edges import EdgeTable


def _dense(table: EdgeTable, n: int) -> dict[tuple[int, int], int]:
    """Every edge as seen from both its ends: (i, j) -> age."""
    out = {}
    for i in range(n):
        ids, slots = table.neighbours(i)
        for j, s in zip(ids.tolist(), slots.tolist(), strict=True):
            out[i, j] = int(table.ages[i, s])
    return out


def test_edges_are_symmetric_through_link_ageing_unlink_and_move():
    t = EdgeTable(6, degree=4)
    for i, j in ((0, 1), (0, 2), (2, 3), (4, 0)):
        t.link(i, j)
    ids, slots = t.neighbours(0)
    assert ids.tolist() == [1, 2, 4]
    assert t.grow_older(0, ids, slots).tolist() == [1, 1, 1]
    t.link(1, 0)  # refreshed, not doubled
    assert _dense(t, 6) == {(0, 1): 0, (1, 0): 0, (0, 2): 1, (2, 0): 1, (0, 4): 1, (4, 0): 1, (2, 3): 0, (3, 2): 0}
    t.unlink(2, 0)
    t.unlink_all(3)  # 2-3 goes, from both ends
    assert not t.has_edges(3) and t.neighbours(2)[0].size == 0
    t.move(4, 3)  # neuron 4 takes slot 3
    assert _dense(t, 6) == {(0, 1): 0, (1, 0): 0, (0, 3): 1, (3, 0): 1}
    assert t.edge_array(6).tolist() == [[0, 1, 0], [0, 3, 1]]


def test_a_full_row_gives_up_its_oldest_edge_at_both_ends():
    t = EdgeTable(8, degree=3)
    for j in (1, 2, 3):
        t.link(0, j)
    t.grow_older(0, *t.neighbours(0))
    t.link(0, 2)  # refreshed: 1 and 3 are now the oldest, 1 first
    t.link(0, 7)
    assert t.neighbours(0)[0].tolist() == [2, 3, 7]
    assert not t.has_edges(1)
    assert (t.ids[:8] <= 8).all()


def test_fill_matches_linking_one_by_one_and_copes_with_repeats_and_overflow():
    rng = np.random.default_rng(0)
    pairs = {tuple(sorted(p)) for p in rng.integers(0, 30, (80, 2)).tolist() if p[0] != p[1]}
    edges = np.array([(i, j, a) for (i, j), a in zip(sorted(pairs), rng.integers(0, 50, len(pairs)), strict=False)])
    filled = EdgeTable(30, degree=16)
    filled.fill(edges)
    assert filled.edge_array(30).tolist() == edges.tolist()
    crowded = EdgeTable(30, degree=2)  # beyond the degree: one at a time, never more than 2 a row
    crowded.fill(np.concatenate([edges, edges[:3]]))
    assert ((crowded.ids > 0).sum(axis=1) <= 2).all()
    assert set(map(tuple, crowded.edge_array(30)[:, :2].tolist())) <= pairs


_LAZY_TABLE = """
import os
from gwr_predictor.learning.edges import EdgeTable

def rss_mb():
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20

before = rss_mb()
t = EdgeTable(1_000_000)  # 64 slots each: 384 MB if written
t.link(999_998, 999_999)
assert t.neighbours(999_999)[0].tolist() == [999_998]
print(rss_mb() - before)
"""


def test_a_new_table_is_zeros_so_memory_comes_with_the_neurons():
    # A process of its own: in the suite's process, other tests' threads and freed heap move RSS too.
    out = subprocess.run([sys.executable, "-c", _LAZY_TABLE], capture_output=True, text=True, timeout=60, check=True)
    assert float(out.stdout) < 50
