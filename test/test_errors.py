"""One exception base: every error class of the package derives from GwrPredictorError, and the
command line turns one into a one-line message and exit code 2 instead of a traceback."""

import ast
import importlib
import inspect
from pathlib import Path

import numpy as np
import pytest

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
    # a walk that misses one subpackage's class (or the nodes') missed modules
    every_part = {"GwrPredictorError", "ParameterError", "DataError", "LearningError", "DefaultPredictorError",
                  "PredictorError", "EvaluationError", "RobotError", "PipelineError", "CommandError",
                  "NodeFatalError"}
    assert every_part <= {c.__name__ for c in found.values()}, sorted(found)
    strays = sorted(n for n, c in found.items() if not issubclass(c, GwrPredictorError))
    assert not strays, f"exception classes not derived from GwrPredictorError: {strays}"


def _exception_classes_by_part() -> dict[str, set[type]]:
    """{subpackage (the nodes are one; "gwr_predictor" for the top-level modules): the exception classes its
    modules define}; an alias (`Other = PipelineError`) is the class it names, counted once."""
    parts: dict[str, set[type]] = {}
    for name in _package_modules():
        if name == "gwr_predictor":
            continue
        module = importlib.import_module(name)
        is_package = hasattr(module, "__path__")
        words = name.split(".")
        part = words[1] if is_package or len(words) > 2 else "gwr_predictor"
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if issubclass(cls, BaseException) and cls.__module__ == module.__name__:
                parts.setdefault(part, set()).add(cls)
    return parts


def test_each_subpackage_defines_one_error_class_at_most():
    # a caller catches one class per subpackage and reads attributes for finer cases (`reason`,
    # `kind_mismatch`): a class per failure made every except clause a guess at which ones a call raises
    parts = _exception_classes_by_part()
    assert {"data", "learning", "pipeline", "robot", "nodes", "gwr_predictor"} <= parts.keys(), sorted(parts)
    limits = {"gwr_predictor": 2}  # the base and the one error of the top-level modules
    over = {part: sorted(c.__qualname__ for c in classes) for part, classes in parts.items()
            if len(classes) > limits.get(part, 1)}
    assert not over, f"more than one exception class in a subpackage: {over}"


#: The parts whose error class has one name: a caller imports and catches that name, not an alias of it
#: (defined by the part or imported from it).
_ONE_NAME_PARTS = ("gwr_predictor", "files", "joints", "parameters", "data", "learning", "default_predictor",
                   "predictors", "evaluation", "pipeline", "robot", "commands", "nodes")


def _part_of(module: str) -> str:
    """The subpackage of a module name ("nodes" for the nodes, "gwr_predictor" for the top-level modules)."""
    words = module.split(".")
    if len(words) > 2 or (len(words) == 2 and hasattr(importlib.import_module(module), "__path__")):
        return words[1]
    return "gwr_predictor"


def test_an_error_class_goes_by_its_own_name_only():
    aliases = []
    for name in _package_modules():
        module = importlib.import_module(name)
        if _part_of(name) not in _ONE_NAME_PARTS:
            continue
        for attr, value in vars(module).items():
            if (isinstance(value, type) and issubclass(value, GwrPredictorError) and attr != value.__name__
                    and _part_of(value.__module__) in _ONE_NAME_PARTS):
                aliases.append(f"{name}.{attr} = {value.__name__}")
    assert not aliases, "aliases of error classes:\n" + "\n".join(aliases)


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


def test_a_checkpoint_whose_read_out_queue_disagrees_with_its_regressors_is_refused_on_load():
    # the read-outs are filed in step with the regressors; a checkpoint that breaks this must fail when
    # loaded, with the checkpoint error, not later on a frame with a TypeError
    from gwr_predictor.default_predictor import LocalLinearParams, LocalLinearPredictor
    from gwr_predictor.learning.errors import LearningError

    model = LocalLinearPredictor(LocalLinearParams())
    t = np.arange(60) / 10.0
    for ti in t:
        model.step(0.3 * np.sin(ti + np.arange(8)))
    header, arrays = model.state()
    assert header["regs_present"] and all(header["regs_present"])
    header["outs_present"][0] = False
    with pytest.raises(LearningError, match="read-out queue"):
        LocalLinearPredictor.from_state(header, arrays)


#: Built-in errors the package must not raise; each module raises its own class instead, also where its own
#: function catches it again (a bare ValueError caught a few lines down is a message that could have been its class).
_BARE = {"ValueError", "RuntimeError", "KeyError"}
#: What the package installs and runs: the library, the nodes, the launch file.
_PRODUCT = ("gwr_predictor", "nodes", "launch")


def _bare_raises(tree: ast.AST) -> list[tuple[str, int, str]]:
    """(function, line, built-in) of every `raise ValueError(...)` (and the like)."""
    found = []

    def visit(node: ast.AST, function: str) -> None:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            function = getattr(node, "name", "<lambda>")
        if isinstance(node, ast.Raise) and node.exc is not None:
            exc = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            if isinstance(exc, ast.Name) and exc.id in _BARE:
                found.append((function, node.lineno, exc.id))
        for child in ast.iter_child_nodes(node):
            visit(child, function)

    visit(tree, "<module>")
    return found


def test_the_scan_finds_bare_raises_caught_or_not_and_lets_the_own_class_pass():
    source = ("def f(x):\n    raise ValueError(x)\n"
              "def g(x):\n    try:\n        raise ValueError(x)\n    except ValueError as e:\n        raise Own(e)\n"
              "def h(x):\n    raise Own(x)\n")
    assert _bare_raises(ast.parse(source)) == [("f", 2, "ValueError"), ("g", 5, "ValueError")]


def test_the_product_raises_its_own_error_classes_not_bare_built_ins():
    strays = []
    for folder in _PRODUCT:
        for path in sorted((ROOT / folder).rglob("*.py")):
            where = path.relative_to(ROOT / folder).as_posix()
            for function, line, name in _bare_raises(ast.parse(path.read_text(), str(path))):
                strays.append(f"{folder}/{where}:{line} {function}: raise {name}")
    assert not strays, "raise the module's GwrPredictorError class instead:\n" + "\n".join(strays)
