"""Angle plots: named (t, angles) series on one subplot per joint, written as PNG.

Generic on purpose: the same figure shows a person's angles, or "person vs prediction vs robot".
Uses matplotlib's object API with the Agg canvas (no pyplot state, no display needed), imported
lazily so that library users who never plot do not pay for matplotlib.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from gwr_predictor.files.user_files import replacing
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.robot.nao import ARM_JOINTS, JOINT_LIMITS


def _checked(series: Mapping[str, tuple[np.ndarray, np.ndarray]], n: int) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    out = {}
    for label, (t, a) in series.items():
        t = np.asarray(t, dtype=float)
        a = np.asarray(a, dtype=float)
        if a.ndim == 1 and n == 1:
            a = a[:, None]
        if t.ndim != 1 or a.shape != (t.shape[0], n):
            raise PipelineError(f"series {label!r}: expected t (T,) and angles (T, {n}), got {t.shape} and {a.shape}")
        out[label] = (t, a)
    return out


def plot_angle_series(path: str | Path, series: Mapping[str, tuple[np.ndarray, np.ndarray]], title: str = "",
                      names: Sequence[str] = ARM_JOINTS,
                      marks: Sequence[float] | Mapping[str, float] | None = None,
                      bands: Mapping[str, tuple[str, np.ndarray, np.ndarray, np.ndarray]] | None = None) -> Path:
    """Draw every series on one subplot per joint (two columns when even) and save a PNG.

    `series` maps a legend label to (t (T,), angles (T, len(names))); NaN rows show as gaps.
    `marks` are times of vertical dashed lines (a mapping labels them, e.g. repetition starts).
    `bands` maps a legend label to (the series it surrounds, t (T,), lower, upper (T, len(names))): a shaded
    band in that series' colour (a stated interval). Known Nao joints get their limits as faint horizontal lines.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    names = tuple(names)
    data = _checked(series, len(names))
    shaded = {}
    for label, (of, t, lo, hi) in (bands or {}).items():
        (t, lo), (_, hi) = _checked({label: (t, lo)}, len(names))[label], _checked({label: (t, hi)}, len(names))[label]
        shaded[label] = (of, t, lo, hi)
    cols = 2 if len(names) % 2 == 0 and len(names) > 1 else 1
    rows = len(names) // cols
    fig = Figure(figsize=(6.5 * cols, 1.9 * rows + 0.8), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, sharex=True, squeeze=False)
    labelled_marks = marks.items() if isinstance(marks, Mapping) else [(None, m) for m in (marks or ())]
    for k, name in enumerate(names):
        # Column-major, so with ARM_JOINTS the left arm is the left column.
        ax = axes[k % rows, k // rows]
        colours = {}
        for label, (t, a) in data.items():
            colours[label] = ax.plot(t, a[:, k], label=label, linewidth=1.2)[0].get_color()
        for label, (of, t, lo, hi) in shaded.items():
            ax.fill_between(t, lo[:, k], hi[:, k], color=colours.get(of, "0.5"), alpha=0.2, linewidth=0, label=label)
        if name in JOINT_LIMITS:  # only limits near the data, so they do not squash it
            lo, hi = ax.get_ylim()
            for lim in JOINT_LIMITS[name]:
                if lo - 0.1 * (hi - lo) <= lim <= hi + 0.1 * (hi - lo):
                    ax.axhline(lim, color="0.6", linewidth=0.6, linestyle=":")
        for mark_label, m in labelled_marks:
            ax.axvline(m, color="0.4", linewidth=0.7, linestyle="--")
            if mark_label and k % rows == 0:
                ax.annotate(mark_label, (m, 1.0), xycoords=("data", "axes fraction"), fontsize=7,
                            va="bottom", ha="left")
        ax.set_ylabel(f"{name}\n(rad)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(alpha=0.3)
        if data:
            ax.legend(fontsize=7, loc="upper right")
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    if title:
        fig.suptitle(title)
    with replacing(path, "plot", PipelineError) as tmp:
        fig.savefig(tmp, dpi=100)
    return Path(path)
