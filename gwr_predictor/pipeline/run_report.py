"""What a recorded pipeline run shows: prediction error at the horizon, robot lag with and without
compensation, neurons per layer, message counts; plus the plot of person vs prediction vs robot.

Pure library code over a bag recorded by the bag_recorder node (read with `gwr_predictor.pipeline.bag_reader`).
Definitions (all times are the stamps inside the messages, one clock):

- prediction MAE at step k: for every /predictions message made at frame t, |P(t+k) - x| over the
  8 joints, where x is the observed /arm_angles frame stamped within half a frame period of
  t + k * period (unmatched predictions, e.g. across a sequence gap, are not scored). "hold" is
  the same for the no-prediction baseline P(t+k) = x(t).
- robot lag: the time shift that best aligns a robot's /joint_states (resampled on a `dt` grid)
  with the person's /arm_angles (linear between frames, NaN across gaps > max_gap_s);
  `lag.estimate_lag`. Tracking MAE is the unshifted mean |robot - person| on the same grid.
- robots: every recorded `<namespace>/joint_states` in the pipeline's namespace or below it; the
  compensator mode of each namespace is read from its delay_compensator's /diagnostics ("mode").
- pipeline: a bag of `run_pipeline.sh --namespace NS` holds `/NS/arm_angles`, ...; the bag's only
  pipeline is read, or the one named (`namespaces.choose_pipeline`), and only its nodes' /diagnostics.
- the stated interval (/prediction_interval, the default's): per step k, the share of the observed frames
  matched as above that fall inside the interval stated at t for t + k, and its mean width (rad).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from gwr_predictor.files.json_safe import to_jsonable
from gwr_predictor.pipeline import bag_messages, bag_reader, conventions, namespaces, plotting
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.robot.errors import RobotError
from gwr_predictor.robot.nao import ARM_JOINTS
from gwr_predictor.robot.tracking import estimate_lag, tracking_error


@dataclass
class Series:
    """Stamped samples: t (N,) seconds and values (N, 8) radians in ARM_JOINTS order."""

    t: np.ndarray
    values: np.ndarray


@dataclass
class RunData:
    """The arrays of one run, read from its bag."""

    bag: Path
    counts: dict[str, int]
    duration_s: float
    person: Series
    predictions_t: np.ndarray  # (N,) stamp of the frame each prediction was made at
    predictions: np.ndarray  # (N, h, 8)
    robots: dict[str, Series]  # namespace ("" = root) -> reported joint states
    modes: dict[str, str]  # namespace -> compensator mode (from /diagnostics)
    learner: dict[str, str]  # last learner status key/values
    rejected: dict[str, int]  # rejection counters (all nodes, last diagnostics)
    #: topic -> (expected type, type found) for every topic that was skipped for its type
    wrong_types: dict[str, tuple[str, str]] = field(default_factory=dict)
    #: one line each: what was skipped and why (the commands print them as warnings)
    warnings: list[str] = field(default_factory=list)
    #: the pipeline's namespace ("" = root): its topics are `<namespace>/arm_angles`, ...
    namespace: str = ""
    #: the interval stated with the predictions (if recorded): stamps (M,), bounds (2, M, h, 8), stated share
    interval_t: np.ndarray = field(default_factory=lambda: np.zeros(0))
    interval_bounds: np.ndarray = field(default_factory=lambda: np.zeros((2, 0, 1, len(ARM_JOINTS))))
    interval_nominal: float | None = None


@dataclass
class PipelineReport:
    """The numbers `gwr-predictor report` prints and writes to report.json."""

    bag: str
    duration_s: float
    message_counts: dict[str, int]
    horizon: int
    frame_period_s: float
    scored_predictions: int
    prediction_mae_rad: float
    prediction_mae_per_step_rad: list[float]
    hold_mae_rad: float
    robots: dict[str, dict[str, Any]] = field(default_factory=dict)
    neurons: dict[str, int] = field(default_factory=dict)
    learner: dict[str, str] = field(default_factory=dict)
    rejected: dict[str, int] = field(default_factory=dict)
    namespace: str = ""
    #: the stated interval, if recorded: its share, and per step the share of the observed angles inside it
    #: and its mean width (rad)
    interval_nominal: float | None = None
    interval_coverage_per_step: list[float] | None = None
    interval_width_per_step_rad: list[float] | None = None

    def to_json(self) -> str:
        return json.dumps(to_jsonable(asdict(self)), indent=2, sort_keys=False)

    def summary_lines(self) -> list[str]:
        h_ms = round(self.horizon * self.frame_period_s * 1000)
        lines = [
            f"bag {self.bag}" + (f" (pipeline {self.namespace})" if self.namespace else "")
            + f": {self.duration_s:.1f} s, "
            + ", ".join(f"{t} {n}" for t, n in sorted(self.message_counts.items()) if n),
            f"prediction error at {h_ms} ms ({self.horizon} frames): MAE {self.prediction_mae_rad:.4f} rad over "
            f"{self.scored_predictions} predictions (holding the last frame instead: {self.hold_mae_rad:.4f} rad)",
            "  per step: " + " ".join(f"{v:.3f}" for v in self.prediction_mae_per_step_rad),
        ]
        if self.interval_coverage_per_step is not None and self.interval_width_per_step_rad is not None:
            lines.append(f"stated {100 * (self.interval_nominal or 0):.0f} % interval, per step: observed angles "
                         "inside " + " ".join(f"{100 * v:.1f} %" for v in self.interval_coverage_per_step)
                         + "; mean width " + " ".join(f"{v:.3f}" for v in self.interval_width_per_step_rad) + " rad")
        for ns, r in self.robots.items():
            lag = "n/a" if r["lag_s"] is None else f"{r['lag_s']:.3f} s"
            mae = "n/a" if r["tracking_mae_rad"] is None else f"{r['tracking_mae_rad']:.4f} rad"
            lines.append(f"robot {ns or '/'} (compensator mode {r['mode']}): lags the person by {lag}, "
                         f"tracking MAE {mae}")
        if self.neurons:
            lines.append("neurons: " + ", ".join(f"{k} {v}" for k, v in self.neurons.items()))
        if self.rejected:
            lines.append("rejected inputs: " + ", ".join(f"{k} {v}" for k, v in self.rejected.items()))
        return lines


# --- reading -------------------------------------------------------------------------------------


def _arm_vector(msg: Any) -> tuple[float, np.ndarray] | None:
    stamp, names, positions = bag_messages.joint_state_arrays(msg)
    index = {n: i for i, n in enumerate(names)}
    if any(n not in index for n in ARM_JOINTS) or positions.size != len(names):
        return None
    return stamp, positions[[index[n] for n in ARM_JOINTS]]


def _series(rows: list[tuple[float, np.ndarray]]) -> Series:
    if not rows:
        return Series(np.zeros(0), np.zeros((0, len(ARM_JOINTS))))
    rows.sort(key=lambda r: r[0])
    return Series(np.array([r[0] for r in rows]), np.vstack([r[1] for r in rows]))


_namespace = namespaces.split_topic  # '/uncompensated/joint_states' -> '/uncompensated'; '/joint_states' -> ''


def expected_type(topic: str, pipeline: str = "") -> str | None:
    """The message type the report and the video read `topic` as (in the pipeline of namespace `pipeline`),
    None for a topic they do not read."""
    for base in (conventions.TOPIC_ANGLES, conventions.TOPIC_PREDICTIONS, conventions.TOPIC_SKELETON,
                 conventions.TOPIC_PREDICTION_INTERVAL):
        if topic == namespaces.in_pipeline(pipeline, base):
            return conventions.TOPIC_TYPES[base]
    for base in (conventions.TOPIC_ROBOT_STATE, conventions.TOPIC_LEARNER_STATUS, conventions.TOPIC_DIAGNOSTICS):
        if _namespace(topic, base) is not None:
            return conventions.TOPIC_TYPES[base]
    return None


def wrong_type_text(topic: str, expected: str, found: str) -> str:
    return f"{topic} has type {found}, expected {expected}"


def _counter(value: str) -> int | None:
    """A counter value from /diagnostics as an int; None for text that is not a finite number."""
    try:
        number = float(value)
    except ValueError:
        return None
    return int(number) if math.isfinite(number) else None


def read_run(bag: str | Path, namespace: str | None = None) -> RunData:
    """Read the topics a report needs from a pipeline bag: the pipeline in `namespace` (e.g. "/robot1"), by
    default the bag's only one. Raises PipelineError / PipelineError."""
    bag = Path(bag)
    info = bag_reader.bag_info(bag)
    pipeline = namespaces.choose_pipeline([t for t, (_, n) in info.topics.items() if n], namespace, bag)
    person: list[tuple[float, np.ndarray]] = []
    pred_t: list[float] = []
    preds: list[np.ndarray] = []
    intervals: list[tuple[float, float, np.ndarray]] = []  # (stamp, share, bounds (2, h, 8))
    robots: dict[str, list[tuple[float, np.ndarray]]] = {}
    modes: dict[str, str] = {}
    learner: dict[str, str] = {}
    diagnostics: dict[str, dict[str, str]] = {}
    angles_topic = namespaces.in_pipeline(pipeline, conventions.TOPIC_ANGLES)
    preds_topic = namespaces.in_pipeline(pipeline, conventions.TOPIC_PREDICTIONS)
    learner_topic = namespaces.in_pipeline(pipeline, conventions.TOPIC_LEARNER_STATUS)
    interval_topic = namespaces.in_pipeline(pipeline, conventions.TOPIC_PREDICTION_INTERVAL)
    undecodable: dict[str, int] = {}
    read: dict[str, int] = {}
    wrong: dict[str, tuple[str, str]] = {}
    for m in bag_reader.read_bag(bag, undecodable=undecodable):
        read[m.topic] = read.get(m.topic, 0) + 1
        expected = expected_type(m.topic, pipeline)
        if expected is not None and m.msgtype != expected:
            wrong.setdefault(m.topic, (expected, m.msgtype))
            continue
        if m.msg is None:
            continue
        if m.topic == angles_topic:
            row = _arm_vector(m.msg)
            if row is not None:
                person.append(row)
        elif m.topic == preds_topic:
            try:
                stamp, names, p = conventions.unpack_predictions(bag_messages.packed_array(m.msg))
            except PipelineError:
                continue
            if names == ARM_JOINTS and (not preds or p.shape == preds[0].shape):
                pred_t.append(stamp)
                preds.append(p)
        elif m.topic == interval_topic:
            try:
                stamp, names, share, lower, upper = conventions.unpack_interval(bag_messages.packed_array(m.msg))
            except PipelineError:
                continue
            if names == ARM_JOINTS and (not intervals or lower.shape == intervals[0][2].shape[1:]):
                intervals.append((stamp, share, np.stack([lower, upper])))
        elif (ns := _namespace(m.topic, conventions.TOPIC_ROBOT_STATE)) is not None:
            row = _arm_vector(m.msg)
            if row is not None and namespaces.within(ns, pipeline):
                robots.setdefault(ns, []).append(row)
        elif m.topic == learner_topic or (not pipeline and m.topic.endswith("/" + conventions.TOPIC_LEARNER_STATUS)):
            for status in m.msg.status:
                learner = {kv.key: kv.value for kv in status.values}
        elif m.topic.endswith("/" + conventions.TOPIC_DIAGNOSTICS):
            for status in m.msg.status:  # /diagnostics is global: only this pipeline's nodes
                if namespaces.within(status.name.rsplit("/", 1)[0], pipeline):
                    diagnostics[status.name] = {kv.key: kv.value for kv in status.values}
    for name, values in diagnostics.items():
        if name.endswith("/delay_compensator") and "mode" in values:
            modes[name[: -len("/delay_compensator")]] = values["mode"]
    bag_reader.check_counts(info, {t: read.get(t, 0) + undecodable.get(t, 0) for t in set(read) | set(undecodable)})
    if angles_topic in wrong:
        raise PipelineError(f"{bag}: {wrong_type_text(angles_topic, *wrong[angles_topic])}; "
                            "the report cannot read the person's angles")
    warnings = [f"{bag}: {wrong_type_text(topic, *types)}; skipped" for topic, types in sorted(wrong.items())
                if topic not in (preds_topic, namespaces.in_pipeline(pipeline, conventions.TOPIC_SKELETON))]
    intervals.sort(key=lambda row: row[0])
    rejected: dict[str, int] = {f"bag:undecodable.{t}": n for t, n in sorted(undecodable.items())}
    for name, values in diagnostics.items():
        for key, value in values.items():
            if key.startswith("rejected."):
                count = _counter(value)
                if count is None:
                    warnings.append(f"{bag}: {name} reports {key} = {value!r}, not a count; skipped")
                else:
                    rejected[f"{name}:{key[len('rejected.'):]}"] = count
    order = np.argsort(pred_t, kind="stable") if pred_t else np.zeros(0, dtype=int)
    return RunData(
        bag=bag,
        counts={t: n for t, (_, n) in info.topics.items()},
        duration_s=info.duration_s,
        person=_series(person),
        predictions_t=np.asarray(pred_t)[order] if pred_t else np.zeros(0),
        predictions=np.stack(preds)[order] if preds else np.zeros((0, 1, len(ARM_JOINTS))),
        robots={ns: _series(rows) for ns, rows in sorted(robots.items())},
        modes=modes,
        learner=learner,
        rejected=rejected,
        wrong_types=wrong,
        warnings=warnings,
        namespace=pipeline,
        interval_t=np.array([row[0] for row in intervals]),
        interval_bounds=(np.stack([row[2] for row in intervals], axis=1) if intervals
                         else np.zeros((2, 0, 1, len(ARM_JOINTS)))),
        interval_nominal=intervals[-1][1] if intervals else None,
    )


# --- computing -----------------------------------------------------------------------------------


def match_frames(person: Series, targets: np.ndarray, tolerance: float) -> np.ndarray:
    """Index of the person frame stamped within `tolerance` of each target time, -1 if none."""
    if person.t.size == 0:
        return np.full(targets.shape, -1)
    pos = np.clip(np.searchsorted(person.t, targets), 1, person.t.size - 1) if person.t.size > 1 else \
        np.zeros(targets.shape, dtype=int)
    if person.t.size > 1:
        left = pos - 1
        pos = np.where(np.abs(person.t[left] - targets) <= np.abs(person.t[pos] - targets), left, pos)
    return np.where(np.abs(person.t[pos] - targets) <= tolerance, pos, -1)


def prediction_errors(run: RunData, period: float) -> tuple[np.ndarray, float, int]:
    """(MAE per step (h,), hold-baseline MAE at h, predictions scored at h)."""
    n, h = run.predictions.shape[:2]
    topic = namespaces.in_pipeline(run.namespace, conventions.TOPIC_PREDICTIONS)
    if n == 0 and topic in run.wrong_types:
        raise PipelineError(f"{run.bag}: {wrong_type_text(topic, *run.wrong_types[topic])}; "
                            "the report cannot read the predictions")
    if n == 0:
        raise PipelineError(f"{run.bag}: no {topic} recorded")
    mae = np.full(h, np.nan)
    for k in range(1, h + 1):
        idx = match_frames(run.person, run.predictions_t + k * period, 0.5 * period)
        ok = idx >= 0
        if ok.any():
            mae[k - 1] = float(np.mean(np.abs(run.predictions[ok, k - 1] - run.person.values[idx[ok]])))
    idx_h = match_frames(run.person, run.predictions_t + h * period, 0.5 * period)
    idx_0 = match_frames(run.person, run.predictions_t, 0.5 * period)
    ok = (idx_h >= 0) & (idx_0 >= 0)
    hold = float(np.mean(np.abs(run.person.values[idx_0[ok]] - run.person.values[idx_h[ok]]))) if ok.any() else math.nan
    return mae, hold, int(ok.sum())


def interval_scores(run: RunData, period: float) -> tuple[list[float], list[float]] | None:
    """Per step k, the share of the observed frames (matched as for the prediction error) inside the interval
    stated for them, and the interval's mean width (rad); None if no interval was recorded."""
    n, h = run.interval_t.size, run.interval_bounds.shape[2]
    if n == 0:
        return None
    coverage, width = [], []
    for k in range(1, h + 1):
        idx = match_frames(run.person, run.interval_t + k * period, 0.5 * period)
        ok = idx >= 0
        lower, upper = run.interval_bounds[0, ok, k - 1], run.interval_bounds[1, ok, k - 1]
        truth = run.person.values[idx[ok]]
        inside = (truth >= lower) & (truth <= upper)
        coverage.append(float(inside.mean()) if inside.size else math.nan)
        width.append(float((upper - lower).mean()) if inside.size else math.nan)
    return coverage, width


def resample(series: Series, grid: np.ndarray, max_gap_s: float) -> np.ndarray:
    """Linear interpolation of a series on `grid`; NaN outside it and across gaps > max_gap_s."""
    out = np.full((grid.size, series.values.shape[1]), np.nan)
    if series.t.size < 2:
        return out
    for j in range(series.values.shape[1]):
        out[:, j] = np.interp(grid, series.t, series.values[:, j], left=np.nan, right=np.nan)
    right = np.clip(np.searchsorted(series.t, grid), 1, series.t.size - 1)
    gap = series.t[right] - series.t[right - 1]
    out[gap > max_gap_s] = np.nan
    return out


def robot_summary(run: RunData, ns: str, dt: float, max_lag_s: float, max_gap_s: float) -> dict[str, Any]:
    """Lag (s) and tracking MAE (rad) of one robot against the person, on a `dt` grid."""
    robot = run.robots[ns]
    result: dict[str, Any] = {"mode": run.modes.get(ns, "unknown"), "states": int(robot.t.size),
                              "lag_s": None, "tracking_mae_rad": None}
    if run.person.t.size < 2 or robot.t.size < 2:
        return result
    start, end = max(run.person.t[0], robot.t[0]), min(run.person.t[-1], robot.t[-1])
    if end - start < 2 * max_lag_s:
        return result
    grid = np.arange(start, end, dt)
    person = resample(run.person, grid, max_gap_s)
    follower = resample(robot, grid, 4 * dt + 0.1)
    try:
        result["lag_s"] = estimate_lag(person, follower, dt, max_lag_s)
        result["tracking_mae_rad"] = tracking_error(person, follower)["mae"]
    except RobotError:
        pass
    return result


def compute_report(run: RunData, period: float = 1.0 / conventions.ANGLE_FPS, dt: float = 0.02,
                   max_lag_s: float = 1.5, max_gap_s: float = conventions.MAX_GAP_S) -> PipelineReport:
    """The report of a run (see the module docstring for the definitions)."""
    if run.person.t.size == 0:
        raise PipelineError(f"{run.bag}: no {namespaces.in_pipeline(run.namespace, conventions.TOPIC_ANGLES)} "
                            "recorded")
    mae, hold, scored = prediction_errors(run, period)
    neurons = {layer: count for layer, key in conventions.NEURON_KEYS.items()
               if (count := _counter(run.learner.get(key, ""))) is not None}
    interval = interval_scores(run, period)
    return PipelineReport(
        bag=str(run.bag), duration_s=run.duration_s, message_counts=run.counts, horizon=int(mae.size),
        frame_period_s=period, scored_predictions=scored, prediction_mae_rad=float(mae[-1]),
        prediction_mae_per_step_rad=[float(v) for v in mae], hold_mae_rad=hold,
        robots={ns: robot_summary(run, ns, dt, max_lag_s, max_gap_s) for ns in run.robots},
        neurons=neurons, learner=run.learner, rejected=run.rejected, namespace=run.namespace,
        interval_nominal=run.interval_nominal,
        interval_coverage_per_step=None if interval is None else interval[0],
        interval_width_per_step_rad=None if interval is None else interval[1])


def plot_run(run: RunData, path: str | Path, seconds: float = 20.0, period: float = 1.0 / conventions.ANGLE_FPS
             ) -> Path:
    """PNG of the last `seconds`: person, h-step prediction (at the time it predicts), each robot."""
    end = run.person.t[-1]
    start = end - seconds

    def window(t: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        keep = (t >= start) & (t <= end)
        return t[keep] - start, v[keep]

    h = run.predictions.shape[1]
    series = {"person": window(run.person.t, _break_gaps(run.person))}
    bands = {}
    predicted = f"prediction +{round(h * period * 1000)} ms"
    if run.predictions.shape[0]:
        pred = Series(run.predictions_t + h * period, run.predictions[:, -1])
        series[predicted] = window(pred.t, _break_gaps(pred))
    if run.interval_t.size and run.interval_bounds.shape[2] == h:  # the interval stated for the same step
        t = run.interval_t + h * period
        lower = window(t, _break_gaps(Series(t, run.interval_bounds[0, :, -1])))
        upper = window(t, run.interval_bounds[1, :, -1])
        bands[f"its stated {100 * (run.interval_nominal or 0):.0f} % interval"] = (predicted, lower[0], lower[1],
                                                                                   upper[1])
    for ns, robot in run.robots.items():
        label = f"robot {ns or '/'} ({run.modes.get(ns, '?')})"
        series[label] = window(robot.t, robot.values)
    name = run.bag.parent.name if run.bag.name == "bag" else run.bag.name  # the run folder's name
    return plotting.plot_angle_series(path, series,
                                      title=f"{name}: person, prediction and robots, last {seconds:.0f} s", bands=bands)


def _break_gaps(series: Series, max_gap_s: float = conventions.MAX_GAP_S) -> np.ndarray:
    """Values with a NaN row wherever the next sample is more than max_gap_s later (lines break there)."""
    values = series.values.copy()
    if series.t.size > 1:
        values[:-1][np.diff(series.t) > max_gap_s] = np.nan
    return values
