"""Watch a recorded run: the person and each simulated Nao side by side, time-aligned, as frames.

Why: the numbers of `gwr-predictor report` say how far a robot lags; a video shows it. A frame has
one panel per body, all seen by the same camera in front of the robot:

- the person: the recorded skeleton as a stick figure (rotated into the person's torso frame and
  scaled to the Nao's size), or, without /skeleton in the bag, the Nao arms the person's angles give;
- one panel per recorded robot (`<namespace>/joint_states`), compensated first, rendered headless
  from the URDF with PyBullet's TinyRenderer, with the person's arm angles at the same instant drawn
  over it as a faint blue "ghost" arm (Nao forward kinematics, projected with the camera's own
  matrices), so a robot in sync covers its ghost and a lagging one trails it;
- captions: the run time, each robot's compensator mode, its current lag (over the last
  `LAG_WINDOW_S`) and tracking error (mean |robot - person| over the last `ERROR_WINDOW_S`).

Times are the stamps inside the messages (one clock, as in `run_report`); the video's t = 0 is the
first /arm_angles frame. Pure library code: `read_video_run` reads a bag, `FrameRenderer` draws
frames, `render_video` writes a file through `video_files`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from gwr_predictor.data.angles import torso_frame
from gwr_predictor.data.errors import DataError
from gwr_predictor.pipeline import bag_messages, bag_reader, conventions, namespaces
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.run_report import RunData, Series, read_run, resample, wrong_type_text
from gwr_predictor.pipeline.video_files import open_video
from gwr_predictor.robot.errors import RobotError
from gwr_predictor.robot.nao import SIDES, UPPER_ARM_LENGTH, forward_kinematics
from gwr_predictor.robot.pybullet_nao import Camera, NaoSimulator
from gwr_predictor.robot.tracking import estimate_lag

if TYPE_CHECKING:
    from PIL.Image import Image as PILImage

#: The camera of every panel: in front of the robot, a little to its left and above (torso frame).
VIDEO_CAMERA = Camera(eye=(0.95, 0.32, 0.16), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), fov_deg=45.0)
GHOST_RGBA = (30, 110, 255, 120)  # the person's arm over a robot: faint blue
PERSON_RGB = (40, 40, 48)
PERSON_ARM_RGB = (30, 110, 255)
CAPTION_HEIGHT = 48  # px under the panels at scale 1 (keeps 240 + 48 a multiple of 16 for MP4)
LAG_WINDOW_S = 6.0
ERROR_WINDOW_S = 2.0
METRIC_DT = 0.05  # grid of the windowed lag / error (s)
MAX_LAG_S = 1.5
NEAR, FAR = 0.02, 5.0  # clip planes of the projection, as in NaoSimulator.render
_BONES = (("head", "neck"), ("neck", "torso"), ("left_shoulder", "right_shoulder"), ("torso", "left_hip"),
          ("torso", "right_hip"), ("left_hip", "right_hip"), ("left_hip", "left_knee"), ("left_knee", "left_foot"),
          ("right_hip", "right_knee"), ("right_knee", "right_foot"))
_ARM_BONES = (("left_shoulder", "left_elbow"), ("left_elbow", "left_hand"), ("right_shoulder", "right_elbow"),
              ("right_elbow", "right_hand"))


@dataclass
class VideoRun:
    """What a video shows, read from one bag: the person (angles, optional skeleton) and the robots."""

    bag: Path
    person: Series  # /arm_angles, ARM_JOINTS order
    robots: dict[str, Series]  # namespace -> joint states, display order (compensated first)
    modes: dict[str, str]  # namespace -> compensator mode ("unknown" when not recorded)
    skeleton_t: np.ndarray  # (N,) stamps of /skeleton (empty: none recorded)
    skeleton: np.ndarray  # (N, J, 3) metres, camera frame
    skeleton_names: tuple[str, ...]
    #: one line each: what was skipped and why (the render command prints them as warnings)
    warnings: list[str] = field(default_factory=list)

    @property
    def t0(self) -> float:
        return float(self.person.t[0])

    @property
    def duration_s(self) -> float:
        return float(self.person.t[-1] - self.person.t[0])


def robot_title(ns: str, mode: str) -> str:
    """'compensated' / 'uncompensated' (plus the namespace unless it says the same) and the mode."""
    kind = "uncompensated" if mode == "none" else "compensated" if mode != "unknown" else "robot"
    where = "" if ns in ("", "/" + kind) else f" {ns}"
    return f"{kind}{where}, mode {mode}"


def _read_skeleton(bag: Path, pipeline: str = "") -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    stamps: list[float] = []
    frames: list[np.ndarray] = []
    names: tuple[str, ...] = ()
    expected = conventions.TOPIC_TYPES[conventions.TOPIC_SKELETON]
    for m in bag_reader.read_bag(bag, topics=[namespaces.in_pipeline(pipeline, conventions.TOPIC_SKELETON)]):
        if m.msg is None or m.msgtype != expected:
            continue  # another type: read_run reported it
        try:
            stamp, these, pos = conventions.unpack_skeleton(bag_messages.packed_array(m.msg))
        except PipelineError:
            continue  # a malformed frame is skipped here as the angle extractor rejects it live
        if not names:
            names = these
        if these == names:
            stamps.append(stamp)
            frames.append(pos)
    if not frames:
        return np.zeros(0), np.zeros((0, 0, 3)), ()
    order = np.argsort(stamps, kind="stable")
    return np.asarray(stamps)[order], np.stack(frames)[order], names


def video_run(run: RunData, skeleton: tuple[np.ndarray, np.ndarray, tuple[str, ...]] | None = None) -> VideoRun:
    """A VideoRun from a report's RunData (and the skeleton, if recorded). Raises PipelineError."""
    topics = ", ".join(sorted(run.counts)) or "nothing"
    if not run.robots or all(r.t.size == 0 for r in run.robots.values()):
        raise PipelineError(f"{run.bag}: no robot in the bag (no <namespace>/{conventions.TOPIC_ROBOT_STATE} with the "
                            f"8 arm joints); it holds: {topics}")
    if run.person.t.size < 2:
        angles = namespaces.in_pipeline(run.namespace, conventions.TOPIC_ANGLES)
        raise PipelineError(f"{run.bag}: fewer than 2 {angles} frames (the person's angles); it holds: {topics}")
    modes = {ns: run.modes.get(ns, "unknown") for ns in run.robots}
    order = sorted((ns for ns, r in run.robots.items() if r.t.size), key=lambda ns: (modes[ns] == "none", ns))
    st, sk, names = skeleton if skeleton is not None else (np.zeros(0), np.zeros((0, 0, 3)), ())
    skipped = [f"{run.bag}: {wrong_type_text(topic, *types)}; skipped" for topic, types in run.wrong_types.items()
               if topic == namespaces.in_pipeline(run.namespace, conventions.TOPIC_SKELETON)]
    return VideoRun(run.bag, run.person, {ns: run.robots[ns] for ns in order}, modes, st, sk, names,
                    [*run.warnings, *skipped])


def read_video_run(bag: str | Path, namespace: str | None = None) -> VideoRun:
    """Read what a video needs from a pipeline bag (the pipeline in `namespace`, by default the bag's only
    one). Raises PipelineError / PipelineError."""
    bag = Path(bag)
    run = read_run(bag, namespace)
    return video_run(run, _read_skeleton(bag, run.namespace))


def parse_span(text: str | None, duration_s: float) -> tuple[float, float]:
    """'A:B' seconds from the run's start (negative: from its end; either side may be empty) -> (a, b)."""
    if text is None or text.strip() in ("", ":"):
        return 0.0, duration_s
    parts = text.split(":")
    if len(parts) != 2:
        raise PipelineError(f"--seconds must be A:B (e.g. 10:30, -20: for the last 20 s), got {text!r}")
    try:
        a = float(parts[0]) if parts[0].strip() else 0.0
        b = float(parts[1]) if parts[1].strip() else duration_s
    except ValueError:
        raise PipelineError(f"--seconds must be A:B with numbers, got {text!r}") from None
    a = a + duration_s if a < 0 else a
    b = b + duration_s if b < 0 else b
    a, b = max(0.0, a), min(duration_s, b)
    if not b > a:
        raise PipelineError(f"--seconds {text!r} selects nothing of the run's {duration_s:.1f} s")
    return a, b


# --- numbers for the captions ----------------------------------------------------------------------


@dataclass
class _Metrics:
    grid: np.ndarray  # absolute stamps
    error: np.ndarray  # (G,) mean |robot - person| over the trailing window, NaN without data
    lag_t: np.ndarray  # stamps at which the lag was estimated (every second)
    lag: np.ndarray  # (L,) seconds, NaN where it cannot be estimated


def _metrics(person: Series, robot: Series, start: float, end: float) -> _Metrics:
    """Windowed tracking error (on a METRIC_DT grid) and lag (once a second) of one robot."""
    grid = np.arange(start - LAG_WINDOW_S, end + METRIC_DT, METRIC_DT)
    p = resample(person, grid, conventions.MAX_GAP_S)
    r = resample(robot, grid, 4 * METRIC_DT + 0.1)
    inst = np.mean(np.abs(r - p), axis=1)  # NaN where either is missing
    ok = np.isfinite(inst)
    n = max(1, round(ERROR_WINDOW_S / METRIC_DT))
    csum = np.concatenate(([0.0], np.cumsum(np.where(ok, inst, 0.0))))
    ccount = np.concatenate(([0], np.cumsum(ok)))
    lo = np.maximum(0, np.arange(grid.size) - n + 1)
    count = ccount[1:] - ccount[lo]
    with np.errstate(invalid="ignore", divide="ignore"):
        error = np.where(count > n // 2, (csum[1:] - csum[lo]) / np.maximum(count, 1), np.nan)
    lag_t = np.arange(start, end + 1.0, 1.0)
    lag = np.full(lag_t.size, np.nan)
    w = round(LAG_WINDOW_S / METRIC_DT)
    for i, t in enumerate(lag_t):
        j = int(np.searchsorted(grid, t))
        a, b = p[max(0, j - w): j + 1], r[max(0, j - w): j + 1]
        if a.shape[0] > 2 * round(MAX_LAG_S / METRIC_DT) + 3:
            try:
                lag[i] = estimate_lag(a, b, METRIC_DT, MAX_LAG_S)
            except RobotError:
                pass
    return _Metrics(grid, error, lag_t, lag)


def _at(t: np.ndarray, values: np.ndarray, when: float) -> float:
    """The last value at or before `when` (NaN if none)."""
    i = int(np.searchsorted(t, when, side="right")) - 1
    return float(values[i]) if i >= 0 else math.nan


def _sample(series: Series, when: float, max_gap_s: float) -> tuple[np.ndarray, bool]:
    """Angles at `when` (linear between samples, held at the ends) and whether they are current data."""
    t = series.t
    i = int(np.searchsorted(t, when))
    if i <= 0:
        return series.values[0], t[0] - when <= max_gap_s
    if i >= t.size:
        return series.values[-1], when - t[-1] <= max_gap_s
    t_a, t_b = t[i - 1], t[i]
    w = (when - t_a) / (t_b - t_a) if t_b > t_a else 1.0
    return (1.0 - w) * series.values[i - 1] + w * series.values[i], t_b - t_a <= max_gap_s


# --- drawing ---------------------------------------------------------------------------------------


class Projector:
    """Torso-frame points -> pixel coordinates with the same matrices TinyRenderer uses."""

    def __init__(self, camera: Camera, width: int, height: int) -> None:
        import pybullet as p

        view = np.array(p.computeViewMatrix(camera.eye, camera.target, camera.up)).reshape(4, 4).T
        proj = np.array(p.computeProjectionMatrixFOV(camera.fov_deg, width / height, NEAR, FAR)).reshape(4, 4).T
        self.matrix = proj @ view
        self.width, self.height = width, height

    def __call__(self, points: np.ndarray) -> np.ndarray:
        """(..., 3) metres -> (..., 2) pixels (x right, y down)."""
        pts = np.asarray(points, dtype=float)
        homo = np.concatenate([pts, np.ones(pts.shape[:-1] + (1,))], axis=-1) @ self.matrix.T
        ndc = homo[..., :2] / homo[..., 3:4]
        # TinyRenderer stores rows bottom-up (row = height - 1 - y): one pixel up from the plain formula
        return np.stack([(ndc[..., 0] + 1.0) * 0.5 * self.width, (1.0 - ndc[..., 1]) * 0.5 * self.height - 1.0],
                        axis=-1)


def arm_polylines(angles: np.ndarray) -> list[np.ndarray]:
    """Per side, the (4, 3) shoulder, elbow, wrist and hand of the Nao at `angles` (ARM_JOINTS order)."""
    fk = forward_kinematics(np.asarray(angles, dtype=float))
    return [np.stack([fk[s].shoulder, fk[s].elbow, fk[s].wrist, fk[s].hand]) for s in SIDES]


def person_points(skeleton: np.ndarray, names: tuple[str, ...]) -> np.ndarray | None:
    """One skeleton frame (camera frame) -> the same joints in the Nao's torso frame at the Nao's size.

    Rotated into the person's own torso frame (so the figure faces the camera like the robots),
    scaled so that the upper arm is the Nao's, and the mid-shoulder put at the Nao's shoulders.
    None when the torso frame cannot be built (missing shoulders or hips).
    """
    try:
        rot, valid = torso_frame(skeleton, names)
    except DataError:
        return None
    if not bool(valid):
        return None
    idx = {n: i for i, n in enumerate(names)}
    mid = 0.5 * (skeleton[idx["left_shoulder"]] + skeleton[idx["right_shoulder"]])
    local = (skeleton - mid) @ rot.T
    arms = [np.linalg.norm(skeleton[idx[f"{s}_elbow"]] - skeleton[idx[f"{s}_shoulder"]])
            for s in ("left", "right") if f"{s}_elbow" in idx and f"{s}_shoulder" in idx]
    arms = [a for a in arms if np.isfinite(a) and a > 1e-3]
    scale = UPPER_ARM_LENGTH / float(np.mean(arms)) if arms else 0.35
    return local * scale + np.array([0.0, 0.0, 0.1])


class FrameRenderer:
    """Draws the frames of one VideoRun; owns a headless PyBullet client (use as a context manager).

    `scale` multiplies every size (panels of 320 x 240 px at 1.0).
    """

    def __init__(self, run: VideoRun, start: float, end: float, *, scale: float = 1.0, ghost: bool = True,
                 camera: Camera = VIDEO_CAMERA) -> None:
        if not (0.1 <= scale <= 4.0):
            raise PipelineError(f"scale must be within 0.1..4, got {scale!r}")
        self.run = run
        self.ghost = ghost
        self.scale = scale
        self.panel_w = 16 * max(1, round(20 * scale))  # multiples of 16: what MP4 encoders want
        self.panel_h = 16 * max(1, round(15 * scale))
        self.caption_h = 16 * max(1, round(CAPTION_HEIGHT / 16 * scale))
        self.width = self.panel_w * (1 + len(run.robots))
        self.height = self.panel_h + self.caption_h
        self.camera = camera
        self.project = Projector(camera, self.panel_w, self.panel_h)
        t0 = run.t0
        self.metrics = {ns: _metrics(run.person, r, t0 + start, t0 + end) for ns, r in run.robots.items()}
        self._sim = NaoSimulator(gravity=False)
        self.empty_scene = self._empty_scene()
        self._cache: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        self._template_image: PILImage | None = None
        from PIL import ImageFont

        self._font = ImageFont.load_default(size=max(8, round(13 * scale)))
        self._small = ImageFont.load_default(size=max(7, round(11 * scale)))

    def __enter__(self) -> FrameRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self._sim.close()

    # --- panels ---------------------------------------------------------------------------------
    def robot_image(self, angles: np.ndarray) -> np.ndarray:
        """The Nao at `angles` (8, ARM_JOINTS order), HxWx3 uint8, as TinyRenderer draws it."""
        self._sim.reset(angles)
        return self._sim.render(self.panel_w, self.panel_h, self.camera)

    def _robot_cached(self, ns: str, angles: np.ndarray) -> np.ndarray:
        """A robot that has not moved is not rendered again (a still robot costs nothing)."""
        old = self._cache.get(ns)
        if old is not None and np.allclose(old[0], angles, atol=1e-5, rtol=0.0):
            return old[1]
        image = self.robot_image(angles)
        self._cache[ns] = (np.array(angles, copy=True), image)
        return image

    def ghost_mask(self, angles: np.ndarray, width: int | None = None) -> np.ndarray:
        """Boolean HxW: the pixels the ghost arm of `angles` covers (`width` px lines; default as drawn)."""
        from PIL import Image, ImageDraw

        mask = Image.new("L", (self.panel_w, self.panel_h), 0)
        self._draw_arms(ImageDraw.Draw(mask), angles, 255, width)
        return np.asarray(mask) > 0

    def _draw_arms(self, draw, angles: np.ndarray, fill, width: int | None = None) -> None:
        """Shoulder-elbow-wrist-hand lines of both arms (dots on the joints unless a width is given)."""
        dots = width is None
        width = max(2, round(7 * self.scale)) if width is None else width
        for line in arm_polylines(angles):
            px = self.project(line)
            draw.line([tuple(p) for p in px], fill=fill, width=width, joint="curve" if dots else None)
            if dots:
                r = width * 0.6
                for x, y in px[1:]:
                    draw.ellipse((x - r, y - r, x + r, y + r), fill=fill)

    def draw_ghost(self, image: np.ndarray, angles: np.ndarray) -> np.ndarray:
        """`image` with the person's arms at `angles` blended over it (faint blue)."""
        from PIL import Image, ImageDraw

        base = Image.fromarray(image).convert("RGBA")
        overlay = Image.new("RGBA", base.size, (0, 0, 0, 0))
        self._draw_arms(ImageDraw.Draw(overlay), angles, GHOST_RGBA)
        return np.asarray(Image.alpha_composite(base, overlay).convert("RGB"))

    def _empty_scene(self) -> np.ndarray:
        """The robots' scene without the robot (moved far below the floor), for the person's panel."""
        sim, p = self._sim, self._sim._p
        # the base pose PyBullet reports is its centre of mass, not the URDF origin: restore it as read
        where, how = p.getBasePositionAndOrientation(sim.robot, physicsClientId=sim.client)
        p.resetBasePositionAndOrientation(sim.robot, [0.0, 0.0, -50.0], how, physicsClientId=sim.client)
        try:
            return sim.render(self.panel_w, self.panel_h, self.camera)
        finally:
            p.resetBasePositionAndOrientation(sim.robot, where, how, physicsClientId=sim.client)

    def person_image(self, when: float) -> tuple[np.ndarray, str]:
        """The person's panel at absolute stamp `when` and its label."""
        from PIL import Image, ImageDraw

        img = Image.fromarray(self.empty_scene.copy())
        draw = ImageDraw.Draw(img)
        run = self.run
        width = max(2, round(6 * self.scale))
        if run.skeleton_t.size:
            i = int(np.clip(np.searchsorted(run.skeleton_t, when, side="right") - 1, 0, run.skeleton_t.size - 1))
            pts = person_points(run.skeleton[i], run.skeleton_names)
            current = abs(run.skeleton_t[i] - when) <= conventions.MAX_GAP_S
            if pts is not None:
                idx = {n: k for k, n in enumerate(run.skeleton_names)}
                px = self.project(pts)
                for bones, colour in ((_BONES, PERSON_RGB), (_ARM_BONES, PERSON_ARM_RGB)):
                    for a, b in bones:
                        if a in idx and b in idx and np.isfinite(px[[idx[a], idx[b]]]).all():
                            draw.line([tuple(px[idx[a]]), tuple(px[idx[b]])], fill=colour, width=width)
                if "head" in idx and np.isfinite(px[idx["head"]]).all():
                    x, y = px[idx["head"]]
                    r = max(0.7 * float(np.linalg.norm(px[idx["head"]] - px[idx["neck"]])) if "neck" in idx else 0.0,
                            2.5 * width)
                    if math.isfinite(r):
                        draw.ellipse((x - r, y - r, x + r, y + r), outline=PERSON_RGB, width=width)
            label = "person (skeleton)" if current and pts is not None else "person (no skeleton now)"
        else:
            angles, current = _sample(run.person, when, conventions.MAX_GAP_S)
            self._draw_arms(draw, angles, PERSON_ARM_RGB)
            label = "person (arm angles)" if current else "person (no data now)"
        return np.asarray(img), label

    # --- whole frames ---------------------------------------------------------------------------
    def _template(self) -> PILImage:
        """The frame's constant parts (background, caption texts), drawn once: text is slow."""
        if self._template_image is None:
            from PIL import Image, ImageDraw

            run = self.run
            image = Image.new("RGB", (self.width, self.height), (250, 250, 250))
            draw = ImageDraw.Draw(image)
            pad = max(2, round(4 * self.scale))
            x = pad + draw.textlength("t = 000.00 s   ", font=self._font)
            draw.text((x, self.panel_h + pad), f"{run.bag.parent.name if run.bag.name == 'bag' else run.bag.name}   "
                      "blue arm over each robot: the person's pose at this instant", fill=(0, 0, 0), font=self._font)
            draw.text((pad, self.panel_h + self.caption_h // 2 + pad // 2),
                      f"lag: best time shift over the last {LAG_WINDOW_S:.0f} s; error: mean |robot - person| over "
                      f"the last {ERROR_WINDOW_S:.0f} s, 8 joints", fill=(90, 90, 90), font=self._small)
            self._template_image = image
        return self._template_image

    def frame(self, t: float) -> np.ndarray:
        """The frame at run time `t` (seconds since the first /arm_angles frame): HxWx3 uint8."""
        from PIL import Image, ImageDraw

        run = self.run
        when = run.t0 + t
        person_angles, person_ok = _sample(run.person, when, conventions.MAX_GAP_S)
        panels = [self.person_image(when)]
        for ns, robot in run.robots.items():
            angles, ok = _sample(robot, when, 4 * METRIC_DT + 0.1)
            image = self._robot_cached(ns, angles)
            if self.ghost and person_ok:
                image = self.draw_ghost(image, person_angles)
            m = self.metrics[ns]
            lag, err = _at(m.lag_t, m.lag, when), _at(m.grid, m.error, when)
            stats = "  ".join((f"lag {lag:.2f} s" if math.isfinite(lag) else "lag -",
                               f"error {err:.2f} rad" if math.isfinite(err) else "error -"))
            title = robot_title(ns, run.modes[ns]) + ("" if ok else " (no data now)")
            panels.append((image, f"{title}\n{stats}"))
        frame = self._template().copy()
        draw = ImageDraw.Draw(frame)
        pad = max(2, round(4 * self.scale))
        for k, (image, label) in enumerate(panels):
            x = k * self.panel_w
            frame.paste(Image.fromarray(image), (x, 0))
            draw.multiline_text((x + pad, pad), label, fill=(0, 0, 0), font=self._font, spacing=2)
            if k:
                draw.line([(x, 0), (x, self.panel_h)], fill=(200, 200, 200), width=1)
        draw.text((pad, self.panel_h + pad), f"t = {t:6.2f} s", fill=(0, 0, 0), font=self._font)
        return np.asarray(frame)


# --- a whole video ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class VideoStats:
    """What render_video wrote."""

    path: Path
    frames: int
    fps: float
    width: int
    height: int
    start_s: float
    end_s: float
    bytes: int
    seconds_taken: float


def render_video(run: VideoRun, path: str | Path, *, span: str | None = None, fps: float = 30.0,
                 scale: float = 1.0, progress: Callable[[int], object] | None = None,
                 progress_total: Callable[[int], object] | None = None) -> VideoStats:
    """Write the video of `run` over `span` ('A:B', see parse_span) at `fps` (real time) to `path`.

    The format follows the suffix (video_files.open_video); `progress(n)` is called after every
    frame with the number written so far, `progress_total(n)` once with the frame count.
    """
    if not (0.5 <= fps <= 60.0):
        raise PipelineError(f"fps must be within 0.5..60, got {fps!r}")
    start, end = parse_span(span, run.duration_s)
    times = np.arange(start, end, 1.0 / fps)
    if times.size == 0:
        raise PipelineError(f"the span {start:.2f}..{end:.2f} s holds no frame at {fps} fps")
    if progress_total is not None:
        progress_total(int(times.size))
    began = time.perf_counter()
    with FrameRenderer(run, start, end, scale=scale) as renderer, \
            open_video(path, fps, (renderer.width, renderer.height)) as video:
        for n, t in enumerate(times, start=1):
            video.write(renderer.frame(float(t)))
            if progress is not None:
                progress(n)
        size = (renderer.width, renderer.height)
    out = Path(path)
    return VideoStats(out, int(times.size), fps, size[0], size[1], start, end, out.stat().st_size,
                      time.perf_counter() - began)
