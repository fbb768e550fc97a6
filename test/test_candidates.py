"""The research candidates for the default (research/candidates.py): each runs online from scratch,
returns (horizon, joints), copes with a missing frame, and cannot see the future."""

from __future__ import annotations

import numpy as np
import pytest

from gwr_predictor.evaluation.online import compare_online
from gwr_predictor.predictors.baselines import HoldLast
from research import candidates
from research.experiments import common
from research.registry import RESEARCH

NAMES = tuple(candidates.CANDIDATES)


def _periodic(n: int = 300) -> np.ndarray:
    t = np.arange(n)[:, None] * 2 * np.pi / 25.0
    return 0.3 + 0.4 * np.sin(t + np.arange(8)[None, :] * 0.4)


def _run(name: str, x: np.ndarray) -> list[np.ndarray | None]:
    model = RESEARCH.make_predictor(name, common.make_params(), 0)
    return [model.step(frame) for frame in x]


@pytest.mark.parametrize("name", NAMES)
def test_runs_with_shapes_and_a_missing_frame(name: str) -> None:
    x = _periodic(120)
    x[60] = np.nan
    outs = _run(name, x)
    shaped = [o for o in outs if o is not None]
    assert len(shaped) >= 100
    assert all(o.shape == (6, 8) and np.isfinite(o).all() for o in shaped)


@pytest.mark.parametrize("name", NAMES)
def test_no_peeking(name: str) -> None:
    """Two streams equal up to frame 150 and different after: every prediction up to 150 is the same."""
    a = _periodic(220)
    b = a.copy()
    b[151:] += np.random.default_rng(0).normal(scale=0.5, size=b[151:].shape)
    pa, pb = _run(name, a)[:151], _run(name, b)[:151]
    assert all((u is None and v is None) or np.array_equal(u, v) for u, v in zip(pa, pb, strict=True))
    later_a, later_b = _run(name, a)[200], _run(name, b)[200]
    assert not np.array_equal(later_a, later_b)  # the differing future does reach the model once observed


def test_long_readout_spans_its_own_frames() -> None:
    model = candidates.long_model(common.make_params(), 0)
    assert model.params.order == 4 and model.linear.weights.shape[0] == candidates.GLOBAL_FRAMES * 8 + 1


def test_experts_learn_a_repeating_motion() -> None:
    """On a sine learned from scratch the gated experts end far below hold-last."""
    res = compare_online({"hold": HoldLast(), "cand": RESEARCH.make_predictor("cand_experts", common.make_params(), 0)},
                         [_periodic(400)], progress=False)
    assert res["cand"].stats.mae[-1] < 0.3 * res["hold"].stats.mae[-1]


class _Offset:
    """A fake expert: the last pose plus a constant offset (always wrong on a still or slow stream)."""

    def __init__(self, offset: float) -> None:
        self.offset, self._last = offset, None

    def reset_sequence(self) -> None:
        self._last = None

    def step(self, x: np.ndarray | None, learn: bool = True) -> np.ndarray | None:
        if x is not None and np.isfinite(x).all():
            self._last = np.asarray(x, dtype=float)
        return None if self._last is None else np.repeat(self._last[None] + self.offset, 6, axis=0)


def _chooser(members: dict, **kw: object) -> candidates.ChooseExperts:
    from research.blend import BlendParams

    return candidates.ChooseExperts(members, BlendParams(horizon=6), **kw)


def test_choose_switches_off_an_expert_worse_than_hold() -> None:
    """An expert with a larger running error than holding still is never the output once both are scored."""
    x = _periodic(200) * 0.1
    model = _chooser({"bad": _Offset(0.5), "hold": HoldLast()})
    outs = [model.step(f) for f in x]
    assert all(np.array_equal(o, np.repeat(f[None], 6, axis=0)) for o, f in zip(outs[20:], x[20:], strict=True))


def test_choose_keeps_the_better_expert_under_hysteresis() -> None:
    """Between two experts whose errors differ by less than the hysteresis, the first chosen stays."""
    x = np.zeros((100, 8))
    model = _chooser({"a": _Offset(0.10), "b": _Offset(0.095)}, hysteresis=0.5)
    outs = [model.step(f) for f in x]
    assert np.allclose(outs[-1], 0.10)  # b is 10 % better in MSE: not enough to switch
    model = _chooser({"a": _Offset(0.10), "b": _Offset(0.095)}, hysteresis=0.0)
    assert np.allclose([model.step(f) for f in x][-1], 0.095)


def test_blend_below_hold_drops_worse_experts() -> None:
    """Blending only the experts at least as good as `worse` (itself included) leaves `bad` out entirely."""
    x = np.zeros((60, 8))
    model = _chooser({"bad": _Offset(0.5), "ok": _Offset(0.01), "worse": _Offset(0.02)}, blend_below="worse")
    out = [model.step(f) for f in x][-1]
    assert np.allclose(out, 0.8 * 0.01 + 0.2 * 0.02, atol=1e-6)  # weights 1 / MSE of ok and worse only


def test_choose_rejects_unknown_members() -> None:
    with pytest.raises(candidates.CandidateError, match="not a member"):
        _chooser({"hold": HoldLast()}, track="llm")
