"""Acclaim ASF skeleton + AMC motion (the CMU mocap database format) -> joint positions.

An `.amc` is read with the `.asf` of the same name beside it, or the one given. Forward kinematics
(Acclaim convention): a bone's `axis ax ay az ORDER` gives C, its dof values in the listed order
give M, both as fixed-axis rotations applied in the listed order (matrix R_last ... R_first); the
bone's global rotation is G = G_parent C M C^-1 and its end is its start plus G (direction *
length), `direction` being a unit vector in the global frame at rest. The root: `position` +
the TX TY TZ of each frame, orientation from its RX RY RZ. Lengths are in the ASF's units:
`:units length L` means a file unit is 1/L inches (the CMU files use 0.45), converted to metres
here. Positions are named after the bone that *starts* there (`lhumerus` = the shoulder, its end
`lhumerus_end` = the elbow = `lradius`), so the naming matches BVH. CMU: Y up.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from gwr_predictor.data.bvh import rotation_matrices
from gwr_predictor.data.errors import DataError
from gwr_predictor.data.mocap_clip import MocapClip
from gwr_predictor.files import limits

INCH_M = 0.0254
_DOF_AXIS = {"rx": "x", "ry": "y", "rz": "z"}
CMU_FPS = 120.0


@dataclass
class AsfBone:
    name: str
    direction: np.ndarray
    length: float
    axis: np.ndarray  # degrees
    axis_order: str  # e.g. "xyz"
    dof: tuple[str, ...] = ()
    parent: str = "root"
    children: list[str] = field(default_factory=list)


@dataclass
class AsfSkeleton:
    bones: dict[str, AsfBone]
    order: list[str]  # parents before children
    root_order: tuple[str, ...]  # e.g. ("tx", "ty", "tz", "rx", "ry", "rz")
    root_axis: str
    root_position: np.ndarray
    root_orientation: np.ndarray
    length_scale: float  # metres per file unit
    degrees: bool


def _fixed_axis(angles_deg: np.ndarray, order: str, degrees: bool = True) -> np.ndarray:
    """(T, k) angles applied about fixed axes in `order` -> (T, 3, 3) R_order[-1] ... R_order[0]."""
    a = np.asarray(angles_deg, dtype=np.float64)
    if not degrees:
        a = np.rad2deg(a)
    return rotation_matrices(a[:, ::-1], order[::-1])


def parse_asf(path: Path) -> AsfSkeleton:
    """The skeleton of an ASF file; errors name the file, the bone and the field."""
    sections: dict[str, list[list[str]]] = {}
    units: dict[str, str] = {}
    current = None
    limits.check_file_size(path, limits.MAX_SKELETON_BYTES, "ASF skeleton", DataError)
    for raw in path.read_text(errors="replace").splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith(":"):
            key, *rest = line[1:].split()
            current = key.lower()
            sections.setdefault(current, [])
            if rest:
                sections[current].append(rest)
            continue
        if current is None:
            raise DataError(f"{path}: text before the first ':section' (not an ASF file?)")
        sections[current].append(line.split())
    for row in sections.get("units", []):
        if len(row) >= 2:
            units[row[0].lower()] = row[1]
    if "bonedata" not in sections or "hierarchy" not in sections:
        raise DataError(f"{path}: needs :bonedata and :hierarchy sections (not an ASF file?)")
    try:
        length_unit = float(units.get("length", "1"))
    except ValueError:
        raise DataError(f"{path}: ':units length' must be a number, got {units['length']!r}") from None
    if not length_unit > 0:
        raise DataError(f"{path}: ':units length' must be positive, got {length_unit}")
    degrees = units.get("angle", "deg").lower().startswith("deg")
    root = {r[0].lower(): r[1:] for r in sections.get("root", []) if r}
    bones = _parse_bones(path, sections["bonedata"])
    order = _parse_hierarchy(path, sections["hierarchy"], bones)
    try:
        root_pos = np.array([float(v) for v in root.get("position", ["0", "0", "0"])])
        root_ori = np.array([float(v) for v in root.get("orientation", ["0", "0", "0"])])
    except ValueError:
        raise DataError(f"{path}: :root position/orientation must be numbers") from None
    return AsfSkeleton(bones, order, tuple(v.lower() for v in root.get("order", ["TX", "TY", "TZ", "RX", "RY",
                                                                                   "RZ"])),
                       root.get("axis", ["XYZ"])[0].lower(), root_pos, root_ori, INCH_M / length_unit, degrees)


def _parse_bones(path: Path, rows: list[list[str]]) -> dict[str, AsfBone]:
    bones: dict[str, AsfBone] = {}
    cur: dict[str, list[str]] | None = None
    for row in rows:
        key = row[0].lower()
        if key == "begin":
            cur = {}
        elif key == "end":
            if cur is None:
                raise DataError(f"{path}: :bonedata 'end' without 'begin'")
            name = (cur.get("name") or ["?"])[0]
            try:
                axis = cur["axis"]
                bone = AsfBone(name, np.array([float(v) for v in cur["direction"]]), float(cur["length"][0]),
                               np.array([float(v) for v in axis[:3]]), axis[3].lower() if len(axis) > 3 else "xyz",
                               tuple(d.lower() for d in cur.get("dof", [])))
            except (KeyError, ValueError, IndexError) as exc:
                raise DataError(f"{path}: bone {name!r}: missing or bad field ({exc}); needs direction, "
                                "length and axis") from None
            if bone.direction.shape != (3,) or bone.axis.shape != (3,):
                raise DataError(f"{path}: bone {name!r}: direction and axis need 3 numbers")
            norm = np.linalg.norm(bone.direction)
            bone.direction = bone.direction / norm if norm > 0 else bone.direction
            bad = [d for d in bone.dof if d not in _DOF_AXIS and d not in ("tx", "ty", "tz", "l")]
            if bad:
                raise DataError(f"{path}: bone {name!r}: unknown dof {bad}")
            bones[name] = bone
            limits.check_count(path, 2 * len(bones) + 1, limits.MAX_JOINTS, "joints (bone starts and ends)",
                               DataError)
            cur = None
        elif cur is not None:
            if key == "limits" or (row[0].startswith("(") and "limits" in cur):
                cur.setdefault("limits", []).extend(row)
            else:
                cur[key] = row[1:]
    return bones


def _parse_hierarchy(path: Path, rows: list[list[str]], bones: dict[str, AsfBone]) -> list[str]:
    """Bones in an order that puts parents first; a bone with two parents (a cycle or a diamond, which
    would be visited exponentially often) is refused, as is a chain deeper than `MAX_DEPTH`."""
    for row in rows:
        if row[0].lower() in ("begin", "end"):
            continue
        parent, children = row[0], row[1:]
        if parent != "root" and parent not in bones:
            raise DataError(f"{path}: :hierarchy names bone {parent!r}, which :bonedata lacks")
        for c in children:
            if c not in bones:
                raise DataError(f"{path}: :hierarchy names bone {c!r}, which :bonedata lacks")
            if bones[c].parent != "root":
                raise DataError(f"{path}: :hierarchy gives bone {c!r} two parents")
            bones[c].parent = parent
            if parent != "root":
                bones[parent].children.append(c)
    order: list[str] = []
    depth = {n: 1 for n, b in bones.items() if b.parent == "root"}
    frontier = deque(depth)
    while frontier:
        name = frontier.popleft()
        order.append(name)
        for child in bones[name].children:
            if child in depth:
                raise DataError(f"{path}: :hierarchy gives bone {child!r} two parents")
            depth[child] = limits.check_count(path, depth[name] + 1, limits.MAX_DEPTH, "levels of bone nesting",
                                              DataError)
            frontier.append(child)
    missing = [n for n in bones if n not in depth]
    if missing:
        raise DataError(f"{path}: bones {missing[:5]} are not connected to the root in :hierarchy")
    return order


def _amc_lines(path: Path) -> Iterator[tuple[int, list[str]]]:
    """Line numbers and tokens of an AMC's data lines (comments and ':' keywords skipped), streamed."""
    with path.open(errors="replace") as fh:
        for n, raw in enumerate(fh, 1):
            line = raw.strip()
            if line and not line.startswith(("#", ":")):
                yield n, line.split()


def _is_frame_number(parts: list[str]) -> bool:
    return len(parts) == 1 and parts[0].isdigit()


def parse_amc(path: Path, skeleton: AsfSkeleton) -> dict[str, np.ndarray]:
    """Per bone (and 'root') the (frames, dof) values of an AMC file. Read twice: once to count the
    frames (checked against the limits), once to fill tables of exactly that size."""
    limits.check_file_size(path, limits.MAX_TEXT_BYTES, "AMC motion", DataError)
    expected = {"root": len(skeleton.root_order), **{n: len(b.dof) for n, b in skeleton.bones.items()}}
    frames = sum(1 for _, parts in _amc_lines(path) if _is_frame_number(parts))
    if not frames:
        raise DataError(f"{path}: no frames (not an AMC file?)")
    limits.check_shape(path, frames, 2 * len(skeleton.bones) + 1, DataError)
    limits.check_count(path, frames * sum(expected.values()), limits.MAX_VALUES, "motion values (frames x dof)",
                       DataError)
    out = {name: np.zeros((frames, width)) for name, width in expected.items() if width or name == "root"}
    has_root = np.zeros(frames, dtype=bool)
    unknown: set[str] = set()
    f = -1
    for n, parts in _amc_lines(path):
        if _is_frame_number(parts):
            f += 1
            continue
        if f < 0:
            raise DataError(f"{path}: line {n}: bone values before the first frame number")
        name = parts[0]
        if name not in expected:
            unknown.add(name)
            continue
        try:
            values = [float(v) for v in parts[1:]]
        except ValueError:
            raise DataError(f"{path}: line {n}: bone {name[:30]!r} has a value that is not a number") from None
        if expected[name] and len(values) != expected[name]:
            raise DataError(f"{path}: frame {f + 1}, bone {name!r}: {len(values)} values, the ASF "
                            f"gives it {expected[name]} dof")
        if name in out:
            out[name][f] = values
        has_root[f] |= name == "root"
    if expected["root"] and not has_root.all():
        raise DataError(f"{path}: frame {int(np.argmin(has_root)) + 1} lacks the root")
    if unknown:
        raise DataError(f"{path}: bones {sorted(unknown)[:5]} are not in the ASF skeleton")
    return out


def forward_kinematics(skeleton: AsfSkeleton, motion: dict[str, np.ndarray]) -> tuple[np.ndarray, list[str]]:
    """Positions (frames, joints, 3) in metres: the root, then each bone's start, then its end; a few
    frames at a time so that the rotations of every bone are never held for the whole clip."""
    frames = motion["root"].shape[0]
    names = ["root", *skeleton.order, *(f"{n}_end" for n in skeleton.order)]
    out = np.empty((frames, len(names), 3))
    for chunk in limits.frame_chunks(frames, 15 * len(names)):
        out[chunk] = _forward_kinematics(skeleton, {k: v[chunk] for k, v in motion.items()})[0]
    return out, names


def _forward_kinematics(skeleton: AsfSkeleton, motion: dict[str, np.ndarray]) -> tuple[np.ndarray, list[str]]:
    root = motion["root"]
    t = root.shape[0]
    col = {k: i for i, k in enumerate(skeleton.root_order)}
    trans = np.stack([root[:, col[a]] if a in col else np.zeros(t) for a in ("tx", "ty", "tz")], axis=1)
    rot_cols = [a for a in skeleton.root_order if a in _DOF_AXIS]
    c_root = _fixed_axis(skeleton.root_orientation[None], skeleton.root_axis, skeleton.degrees)[0]
    m_root = _fixed_axis(root[:, [col[a] for a in rot_cols]], "".join(_DOF_AXIS[a] for a in rot_cols),
                         skeleton.degrees)
    glob = {"root": c_root @ m_root @ c_root.T}
    start = {"root": (skeleton.root_position + trans) * skeleton.length_scale}
    names, positions = ["root"], [start["root"]]
    end: dict[str, np.ndarray] = {}
    for name in skeleton.order:
        b = skeleton.bones[name]
        c = _fixed_axis(b.axis[None], b.axis_order, skeleton.degrees)[0]
        rot_dof = [d for d in b.dof if d in _DOF_AXIS]
        if rot_dof:
            vals = motion[name][:, [b.dof.index(d) for d in rot_dof]]
            m = _fixed_axis(vals, "".join(_DOF_AXIS[d] for d in rot_dof), skeleton.degrees)
        else:
            m = np.broadcast_to(np.eye(3), (t, 3, 3))
        parent = b.parent
        glob[name] = glob[parent] @ (c @ m @ c.T)
        s = start["root"] if parent == "root" else end[parent]
        start[name] = s
        end[name] = s + np.einsum("tij,j->ti", glob[name], b.direction * b.length * skeleton.length_scale)
        names.append(name)
        positions.append(s)
    for name in skeleton.order:
        names.append(f"{name}_end")
        positions.append(end[name])
    return np.stack(positions, axis=1), names


def find_asf(amc: Path, asf: str | Path | None) -> Path:
    """The ASF for `amc`: the one given, else `<stem>.asf` beside it, else the only .asf there."""
    if asf:
        p = Path(asf)
        if not p.is_file():
            raise DataError(f"{p}: no such ASF file (given for {amc})")
        return p
    same = amc.with_suffix(".asf")
    if same.is_file():
        return same
    subject = amc.parent / f"{amc.stem.split('_')[0]}.asf"  # CMU: 02_01.amc goes with 02.asf
    if subject.is_file():
        return subject
    others = sorted(amc.parent.glob("*.asf"))
    if len(others) == 1:
        return others[0]
    raise DataError(f"{amc}: no skeleton {same.name} beside it ({len(others)} other .asf there); give --asf FILE")


def load_amc(path: str | Path, asf: str | Path | None = None) -> MocapClip:
    """An AMC motion with its ASF skeleton as a `MocapClip` in metres, 120 fps (CMU), Y up."""
    path = Path(path)
    if path.suffix.lower() == ".asf":
        raise DataError(f"{path}: an .asf holds only the skeleton; give the .amc motion file (with --asf)")
    asf_path = find_asf(path, asf)
    skeleton = parse_asf(asf_path)
    positions, names = forward_kinematics(skeleton, parse_amc(path, skeleton))
    return MocapClip(positions, tuple(names), CMU_FPS, str(path), up="y", scale_known=True,
                     metadata={"format": "asf/amc", "asf": str(asf_path)})
