"""The default's point predictions stay bit for bit what they were: what is added beside them (the spread)
or changes how they are computed without meaning to move them changes none of them.

`data/default_points.json` holds, per frame of a fixed stream (a movement performed again and again with
variation, pauses, tracker noise, lost frames and a sequence reset, so that the memory recognises it and
both weightings are returned), the SHA-256 of the default's prediction as the code made it when the file
was last written (the memories' fit in its neighbour-by-neighbour form, 1e-15 from the form before).
Rewrite it only for a change that is meant to move the point predictions:
`python test/test_point_predictions.py --write`.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path

import numpy as np

FIXTURE = Path(__file__).parent / "data" / "default_points.json"


def stream() -> list[np.ndarray]:
    """Two sequences of 8 joint angles (rad): a movement performed five times, each with its own speed,
    size and pause, with 1 % tracker noise and three lost frames; then a new sequence of another one."""
    rng = np.random.default_rng(49)
    phase = np.linspace(0.0, 1.0, 8)

    def performance(speed: float, size: float, pause: int, shape: float) -> np.ndarray:
        t = np.linspace(0.0, 1.0, round(30 / speed))[:, None]
        move = size * (0.6 * np.sin(np.pi * t) ** 2 * np.cos(shape * phase) + 0.2 * np.sin(2 * np.pi * (t + phase)))
        rest = np.repeat(move[:1], pause, axis=0)
        return np.concatenate([rest, move])

    first = np.concatenate([performance(s, a, p, 1.0) for s, a, p in
                            zip((1.0, 0.85, 1.2, 0.95, 1.1), (1.0, 1.08, 0.93, 1.0, 1.05), (6, 10, 4, 8, 5),
                                strict=True)])
    first = first + 0.01 * rng.normal(size=first.shape)
    first[[40, 41, 95]] = np.nan
    second = np.concatenate([performance(s, a, 5, 3.0) for s, a in ((1.0, 1.0), (0.9, 1.1))])
    second = second + 0.01 * rng.normal(size=second.shape)
    return [first, second]


def digests() -> tuple[list[str], int]:
    """Per frame the SHA-256 of the default's prediction ("none" where it made none), and the frames on
    which it returned its ungated weighting."""
    import gwr_predictor as gp

    model = gp.make_default()
    out = []
    for i, seq in enumerate(stream()):
        if i:
            model.reset_sequence()
        for frame in seq:
            pred = model.step(None if np.isnan(frame).any() else frame)
            out.append("none" if pred is None else hashlib.sha256(np.ascontiguousarray(pred, float).tobytes()
                                                                   ).hexdigest())
    return out, int(model.recognised)


def test_point_predictions_are_those_the_fixture_holds():
    saved = json.loads(FIXTURE.read_text())
    now, recognised = digests()
    assert recognised == saved["recognised"] and recognised > 20  # both weightings' paths are in the stream
    assert len(now) == len(saved["digests"])
    differ = [i for i, (a, b) in enumerate(zip(now, saved["digests"], strict=True)) if a != b]
    assert not differ, f"{len(differ)} of {len(now)} point predictions changed, the first at frame {differ[0]}"


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        raise SystemExit("usage: python test/test_point_predictions.py --write")
    hashes, recognised = digests()
    FIXTURE.parent.mkdir(exist_ok=True)
    FIXTURE.write_text(json.dumps({"recognised": recognised, "digests": hashes}, indent=0) + "\n")
    print(f"{FIXTURE}: {len(hashes)} frames, {recognised} recognised")
