"""The product's predictions stay what they were, bit for bit, through a redesign of how they are built.

Three fixed streams of 8 Nao arm angles at 10 fps run through every predictor the learner node can run:
- `repeated`: a movement performed five times with variation, pauses, tracker noise, lost frames and a
  sequence reset, so that the default's memory recognises it and both of its weightings are returned;
- `demonstrator`: two patterns of the built-in demonstrator, two repetitions each, one sequence each;
- `real`: the arm angles of a real person climbing (`data/climb_2_arm_angles.npy`, see data/README.md);
and through the default a fourth, `long`: 3,400 frames of motion that keeps being new, so that its gates
end their warm-up and its memories pass `FLOAT32_ABOVE` snippets (their float32 search runs).

`data/bit_identical.npz` holds, per predictor, stream and frame, the first 64 bits of the SHA-256 of the
prediction as the code made it when the file was written, and two float64 checksums of it. Where the
BLAS kernel is the one that wrote the file, every frame must hash the same (bit-identical). Elsewhere
(another CPU picks other BLAS kernels, whose sums round differently by ~1e-15) the checksums must agree to
1e-9. A prediction moved on purpose rewrites the file: `python test/test_bit_identical.py --write`.
"""

from __future__ import annotations

import hashlib
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data"
FIXTURE = DATA / "bit_identical.npz"
REAL = DATA / "climb_2_arm_angles.npy"
PREDICTORS = ("gwr_experts", "gated_llm_gwr", "hierarchy", "rls_ar", "linear")
STREAMS = ("repeated", "demonstrator", "real")
#: (predictor, stream) pairs the fixture holds: every predictor on every stream, and the default on `long`
CASES = (*((p, s) for p in PREDICTORS for s in STREAMS), ("gwr_experts", "long"))
#: Weights of the second checksum: a change that only permutes values moves it.
_WEIGHTS = 1.0 + np.arange(6 * 8).reshape(6, 8) / 48.0


def repeated() -> list[np.ndarray]:
    """Two sequences: a movement performed five times, each with its own speed, size and pause, with 1 %
    tracker noise and three lost frames (NaN); then a new sequence of another one."""
    rng = np.random.default_rng(49)
    phase = np.linspace(0.0, 1.0, 8)

    def performance(speed: float, size: float, pause: int, shape: float) -> np.ndarray:
        t = np.linspace(0.0, 1.0, round(30 / speed))[:, None]
        move = size * (0.6 * np.sin(np.pi * t) ** 2 * np.cos(shape * phase) + 0.2 * np.sin(2 * np.pi * (t + phase)))
        return np.concatenate([np.repeat(move[:1], pause, axis=0), move])

    first = np.concatenate([performance(s, a, p, 1.0) for s, a, p in
                            zip((1.0, 0.85, 1.2, 0.95, 1.1), (1.0, 1.08, 0.93, 1.0, 1.05), (6, 10, 4, 8, 5),
                                strict=True)])
    first = first + 0.01 * rng.normal(size=first.shape)
    first[[40, 41, 95]] = np.nan
    second = np.concatenate([performance(s, a, 5, 3.0) for s, a in ((1.0, 1.0), (0.9, 1.1))])
    return [first, second + 0.01 * rng.normal(size=second.shape)]


def demonstrator() -> list[np.ndarray]:
    from gwr_predictor.data.demonstrator import demonstrate
    from gwr_predictor.data.extraction import extract_angles

    return [extract_angles(s.positions, s.timestamps, s.joint_names).angles
            for s in demonstrate(("wave_one", "raise_front_both"), subjects=1, repetitions=2, seed=3)]


def real() -> list[np.ndarray]:
    return [np.load(REAL)]


def long() -> list[np.ndarray]:
    """3,400 frames of smooth motion that keeps being new (each joint's velocity a damped random walk about
    a resting pose), with three lost frames: nearly every frame is a new snippet."""
    rng = np.random.default_rng(46)
    pose, velocity, out = np.zeros(8), np.zeros(8), np.empty((3400, 8))
    for t in range(len(out)):
        velocity = 0.95 * velocity + 0.004 * rng.normal(size=8)
        pose = 0.995 * pose + velocity
        out[t] = pose
    out[[700, 701, 1900]] = np.nan
    return [out]


def stream(name: str) -> list[np.ndarray]:
    return {"repeated": repeated, "demonstrator": demonstrator, "real": real, "long": long}[name]()


def frames(model: object, sequences: list[np.ndarray]) -> Iterator[np.ndarray | None]:
    """`model`'s prediction at each frame of `sequences` (a sequence reset between them)."""
    for i, seq in enumerate(sequences):
        if i:
            model.reset_sequence()  # type: ignore[attr-defined]
        for frame in seq:
            yield model.step(None if np.isnan(frame).any() else frame)  # type: ignore[attr-defined]


def fingerprints(predictions: list[np.ndarray | None]) -> tuple[np.ndarray, np.ndarray]:
    """(64-bit hash per frame, (frames, 2) checksums) of predictions; None hashes to 0 and sums to NaN."""
    hashes = np.zeros(len(predictions), np.uint64)
    sums = np.full((len(predictions), 2), np.nan)
    for i, p in enumerate(predictions):
        if p is None:
            continue
        p = np.ascontiguousarray(p, float)
        hashes[i] = int.from_bytes(hashlib.sha256(p.tobytes()).digest()[:8], "little")
        sums[i] = p.sum(), (p * _WEIGHTS[:p.shape[0], :p.shape[1]]).sum()
    return hashes, sums


def run(predictor: str, name: str) -> list[np.ndarray | None]:
    from gwr_predictor.registry import make_predictor

    return list(frames(make_predictor(predictor), stream(name)))


def blas_kernel() -> str:
    """The BLAS and the kernel it chose for this CPU: where they differ, sums may round differently."""
    from threadpoolctl import threadpool_info

    return ";".join(f"{i['internal_api']}:{i.get('architecture')}" for i in threadpool_info()
                    if i.get("user_api") == "blas")


@pytest.fixture(scope="module")
def saved() -> dict[str, np.ndarray]:
    with np.load(FIXTURE) as f:
        return dict(f)


@pytest.mark.parametrize(("predictor", "name"), CASES)
def test_predictions_are_those_the_fixture_holds(saved, predictor, name):
    hashes, sums = fingerprints(run(predictor, name))
    want_hashes, want_sums = saved[f"{predictor}/{name}/hash"], saved[f"{predictor}/{name}/sums"]
    assert hashes.shape == want_hashes.shape, f"{len(hashes)} frames, the fixture holds {len(want_hashes)}"
    np.testing.assert_array_equal(hashes == 0, want_hashes == 0, err_msg="predictions made on other frames")
    if str(saved["blas"]) == blas_kernel():
        differ = np.flatnonzero(hashes != want_hashes)
        assert not differ.size, f"{differ.size} of {len(hashes)} predictions changed, the first at frame {differ[0]}"
    else:
        np.testing.assert_allclose(sums, want_sums, rtol=1e-9, atol=1e-9, equal_nan=True)


def test_the_long_stream_takes_the_default_past_its_warm_up_and_into_the_float32_search():
    from gwr_predictor.default_predictor.memory import FLOAT32_ABOVE
    from gwr_predictor.registry import make_predictor

    model = make_predictor("gwr_experts")
    list(frames(model, long()))
    memories = [m.model for n, m in model.experts.members.items() if n in ("memory", "long_memory")]
    assert min(m.size for m in memories) > FLOAT32_ABOVE + 200
    warmup = model.experts.members["memory"].params.warmup
    assert 0 < warmup < int(model.experts.members["memory"]._scored.min())


def test_the_default_recognises_the_repeated_stream():
    """Both of the default's weightings (ungated where it recognises the motion) are in the fixture."""
    from gwr_predictor.registry import make_predictor

    model = make_predictor("gwr_experts")
    list(frames(model, repeated()))
    assert model.recognised > 20


@pytest.mark.parametrize("predictor", ("gwr_experts", "gated_llm_gwr", "hierarchy"))
def test_a_checkpoint_midway_continues_bit_for_bit(tmp_path, predictor):
    from gwr_predictor.registry import load_predictor, make_predictor

    sequence = real()[0]
    whole = list(frames(make_predictor(predictor), [sequence]))
    model = make_predictor(predictor)
    half = len(sequence) // 2
    first = list(frames(model, [sequence[:half]]))
    model.save(tmp_path / "midway.npz")
    resumed = load_predictor(predictor, tmp_path / "midway.npz")
    rest = [resumed.step(frame) for frame in sequence[half:]]
    assert fingerprints(first + rest)[0].tolist() == fingerprints(whole)[0].tolist()


def write() -> None:
    out: dict[str, np.ndarray] = {"blas": np.array(blas_kernel())}
    for predictor, name in CASES:
        out[f"{predictor}/{name}/hash"], out[f"{predictor}/{name}/sums"] = fingerprints(run(predictor, name))
    np.savez_compressed(FIXTURE, **out)
    print(f"{FIXTURE}: {len(CASES)} predictor x stream cases, BLAS {out['blas']}")


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        raise SystemExit("usage: python test/test_bit_identical.py --write")
    write()
