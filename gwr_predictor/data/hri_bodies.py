"""ROS4HRI bodies (REP-155) -> the 8 Nao arm angles, and which tracked body to follow; no ROS here.

A REP-155 body tracker (hri_fullbody: MediaPipe on an RGB or RGB-D camera) lists the ids of the
bodies it tracks on `/humans/bodies/tracked` (hri_msgs/IdsList: header, ids string[]) and publishes,
per body, `/humans/bodies/<id>/joint_states`: a sensor_msgs/JointState of the human kinematic model
(ros4hri human_description), each joint named `<joint>_<id>`. Each arm of that model is a chain
below the `torso_<id>` frame (x forward, y left, z up: the Nao torso frame's axes):

    <s>_y_shoulder  about z (-z on the left, +z on the right)   swings the raised arm forward
    <s>_p_shoulder  about x (+x on the left, -x on the right)   raises the arm sideways
    <s>_r_shoulder  about the upper arm (+z left, -z right)     turns the arm about itself
    <s>_elbow       about -y                                    flexion, 0 = straight
    the upper arm and the forearm hang along -z at zero angles.

`arm_directions` is that chain's forward kinematics: the unit upper arm u and forearm f in the torso
frame. They go through `gwr_predictor.data.angles.arm_angles`, the inversion the skeleton path
uses, then the same clip into the Nao limits: one set of sign conventions, singularity rules and
limits whatever the tracker (docs/real_robot.md has the table).

The body's distance is not in its joint states (the model's root is the body frame itself), so
`choose_body` can pick the nearest body only from positions the caller obtains elsewhere
(hri_fullbody's `/humans/bodies/<id>/position`, a PointStamped in the camera frame).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from gwr_predictor.data.angles import arm_angles
from gwr_predictor.data.errors import DataError
from gwr_predictor.joints.names import MAX_JOINTS, MAX_NAME_CHARS
from gwr_predictor.robot.nao import SIDES, clip_to_limits, rot_x, rot_y, rot_z

#: REP-155's namespace of the bodies and its topics below it.
BODIES_NAMESPACE = "/humans/bodies"
TRACKED_TOPIC = "tracked"
JOINT_STATES_TOPIC = "joint_states"
POSITION_TOPIC = "position"
IDS_LIST_TYPE = "hri_msgs/msg/IdsList"

#: The four arm joints of the human model per side, in the order `arm_directions` reads them.
ARM_CHAIN = ("y_shoulder", "p_shoulder", "r_shoulder", "elbow")
_PREFIX = {"L": "l", "R": "r"}
#: The 8 human joints the Nao arm angles need (left chain, then right), without the body id suffix.
HUMAN_ARM_JOINTS: tuple[str, ...] = tuple(f"{_PREFIX[s]}_{j}" for s in SIDES for j in ARM_CHAIN)
_REFLECT = {"L": 1.0, "R": -1.0}
_DOWN = np.array([0.0, 0.0, -1.0])
#: Body ids that can be a topic name token (letters, digits, underscores).
_ID_PATTERN = re.compile(r"[A-Za-z0-9_]+")

SELECTIONS = ("first", "nearest")


def valid_body_id(body_id: str) -> bool:
    """True if `body_id` can name a topic below the bodies namespace."""
    return bool(_ID_PATTERN.fullmatch(body_id))


def body_topic(namespace: str, body_id: str, topic: str) -> str:
    """`<namespace>/<id>/<topic>`, e.g. /humans/bodies/b1/joint_states."""
    if not valid_body_id(body_id):
        raise DataError(f"body id {body_id!r} cannot be part of a topic name (letters, digits, _ only)")
    return f"{namespace.rstrip('/')}/{body_id}/{topic}"


def ids_from_topics(topic_names: Iterable[str], namespace: str = BODIES_NAMESPACE) -> list[str]:
    """Body ids that have a joint_states topic in the ROS graph, sorted: the tracked list when no
    hri_msgs/IdsList can be received."""
    pattern = re.compile(re.escape(namespace.rstrip("/")) + r"/([A-Za-z0-9_]+)/" + JOINT_STATES_TOPIC)
    return sorted({m.group(1) for t in topic_names if (m := pattern.fullmatch(t))})


def check_frame(frame_id: str, body_id: str) -> None:
    """A body's joint states name no frame, or one of that body's (REP-155 suffixes a body's frames with its id:
    `body_<id>`, `torso_<id>`, ...): another body's frame means crossed topics (reason `frame_id`)."""
    if frame_id and not frame_id.endswith(f"_{body_id}"):
        raise DataError(f"frame {frame_id[:80]!r} is not a frame of body {body_id} (expected '' or "
                        f"'<link>_{body_id}', e.g. 'body_{body_id}')", "frame_id")


def body_arm_joints(names: Sequence[str], positions: np.ndarray, body_id: str) -> np.ndarray:
    """One body's JointState names and positions -> its 8 arm joint angles (rad) in `HUMAN_ARM_JOINTS`
    order. Names are `<joint>_<id>` (hri_fullbody) or bare `<joint>`; the other joints are ignored.
    More than `MAX_JOINTS` names, or a name longer than `MAX_NAME_CHARS`, is refused before anything is
    sized by them (reason `too_large`)."""
    if len(names) > MAX_JOINTS:
        raise DataError(f"{len(names)} joint names exceed the limit of {MAX_JOINTS}", "too_large")
    if max(map(len, names), default=0) > MAX_NAME_CHARS:
        raise DataError(f"a joint name longer than {MAX_NAME_CHARS} characters", "too_large")
    positions = np.asarray(positions, dtype=np.float64).ravel()
    if positions.size != len(names):
        raise DataError(f"{len(names)} joint names but {positions.size} positions", "layout")
    index: dict[str, int] = {}
    suffix = f"_{body_id}"
    for i, name in enumerate(names):
        bare = name[: -len(suffix)] if body_id and name.endswith(suffix) else name
        if bare in index:
            raise DataError(f"joint {bare!r} appears twice", "layout")
        index[bare] = i
    missing = [j for j in HUMAN_ARM_JOINTS if j not in index]
    if missing:
        raise DataError(f"missing joints {missing} (expected names like '{HUMAN_ARM_JOINTS[0]}{suffix}')",
                        "missing_joints")
    angles = positions[[index[j] for j in HUMAN_ARM_JOINTS]]
    if not np.all(np.isfinite(angles)):
        raise DataError("NaN or inf among the arm joint positions", "non_finite")
    return angles


def arm_directions(chain: np.ndarray, side: str) -> tuple[np.ndarray, np.ndarray]:
    """Human model FK of one arm: chain angles (..., 4) in `ARM_CHAIN` order -> unit upper arm u and
    forearm f (..., 3) in the torso frame."""
    chain = np.asarray(chain, dtype=np.float64)
    r = _REFLECT[side]
    shoulder = rot_z(-r * chain[..., 0]) @ rot_x(r * chain[..., 1]) @ rot_z(r * chain[..., 2])
    u = shoulder @ _DOWN
    f = shoulder @ rot_y(-chain[..., 3]) @ _DOWN
    return u, f


def body_to_nao(human: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Human arm joints (..., 8) in `HUMAN_ARM_JOINTS` order -> (Nao angles clipped, unclipped), each
    (..., 8) in `ARM_JOINTS` order, by the skeleton path's inversion and clip."""
    human = np.asarray(human, dtype=np.float64)
    if human.shape[-1:] != (len(HUMAN_ARM_JOINTS),):
        raise DataError(f"expected (..., {len(HUMAN_ARM_JOINTS)}) human arm angles, got shape {human.shape}")
    k = len(ARM_CHAIN)
    raw = np.concatenate([arm_angles(*arm_directions(human[..., i * k:(i + 1) * k], side), side)
                          for i, side in enumerate(SIDES)], axis=-1)
    return clip_to_limits(raw), raw


def choose_body(tracked: Sequence[str], current: str | None, selection: str = "first",
                distances: Mapping[str, float] | None = None, switch_margin_m: float = 0.2) -> str | None:
    """The body to follow among the tracked ids (None if there is none).

    first: keep the current body while it is tracked, else the first id of the list.
    nearest: the body with the smallest known distance (m); the current one is kept unless another is
    nearer by more than `switch_margin_m` (a person at the same distance does not take over); bodies
    without a known distance come after those with one, and without any distance it is `first`.
    """
    if selection not in SELECTIONS:
        raise DataError(f"selection must be one of {SELECTIONS}, got {selection!r}")
    ids = [i for i in tracked if valid_body_id(i)]
    if not ids:
        return None
    kept = current if current in ids else None
    known = {i: float(distances[i]) for i in ids if distances and np.isfinite(distances.get(i, np.nan))}
    if selection == "first" or not known:
        return kept or ids[0]
    nearest = min(known, key=lambda i: (known[i], i))
    if kept is None:
        return nearest
    if kept not in known or known[nearest] < known[kept] - switch_margin_m:
        return nearest
    return kept
