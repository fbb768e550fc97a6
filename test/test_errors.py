"""One exception base: every error class of the package derives from GwrPredictorError, and the
command line turns one into a one-line message and exit code 2 instead of a traceback."""

import importlib
import inspect
from pathlib import Path

import numpy as np

from gwr_predictor.commands.cli import main
from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.robot.nao import ARM_JOINTS

ROOT = Path(__file__).resolve().parents[1]


def _package_modules() -> list[str]:
    names = []
    for folder, prefix in ((ROOT / "gwr_predictor", "gwr_predictor"), (ROOT / "nodes", "gwr_predictor.nodes")):
        base = ROOT / "gwr_predictor" if prefix == "gwr_predictor" else ROOT / "nodes"
        for path in sorted(folder.rglob("*.py")):
            parts = list(path.relative_to(base).with_suffix("").parts)
            if parts[-1] == "__main__":  # importing it runs the command line
                continue
            if parts[-1] == "__init__":
                parts = parts[:-1]
            names.append(".".join([prefix, *parts]))
    return names


def test_every_exception_class_of_the_package_derives_from_the_base():
    found = {}
    for name in _package_modules():
        module = importlib.import_module(name)
        for cls_name, cls in inspect.getmembers(module, inspect.isclass):
            if issubclass(cls, BaseException) and cls.__module__ == module.__name__:
                found[f"{name}.{cls_name}"] = cls
    # the package defines many; a walk that finds few means it missed modules
    assert len(found) >= 25, sorted(found)
    strays = sorted(n for n, c in found.items() if not issubclass(c, GwrPredictorError))
    assert not strays, f"exception classes not derived from GwrPredictorError: {strays}"


def test_corrupt_checkpoint_is_one_line_and_exit_2(tmp_path, capsys):
    recording = tmp_path / "angles.csv"
    t = np.arange(40) / 10.0
    rows = ["time," + ",".join(ARM_JOINTS)]
    rows += [f"{ti:.1f}," + ",".join(f"{0.1 * np.sin(ti + j):.4f}" for j in range(8)) for ti in t]
    recording.write_text("\n".join(rows) + "\n")
    corrupt = tmp_path / "corrupt.npz"
    corrupt.write_bytes(b"not a zip file at all")
    code = main(["evaluate", str(recording), "--checkpoint", str(corrupt), "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    assert str(corrupt) in err
