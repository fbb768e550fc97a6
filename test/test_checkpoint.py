"""Checkpoints: exact continuation after save/load, file format, atomic writes, clear errors."""

import json
import os

import numpy as np
import pytest

from gwr_predictor.learning import checkpoint
from gwr_predictor.learning.checkpoint import FORMAT_VERSION, MAGIC, read_checkpoint, write_checkpoint
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.hierarchy import FlatPredictor, Hierarchy
from gwr_predictor.learning.params import HierarchyParams


def movement(n: int, offset: int = 0) -> np.ndarray:
    t = np.arange(offset, offset + n)[:, None]
    phase = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    return 0.8 * np.sin(2 * np.pi * t / 27 + phase) + 0.1 * np.sin(2 * np.pi * t / 11 + 2 * phase)


def trained(cls=Hierarchy, mode="recursive", frames=250):
    model = cls(HierarchyParams(mode=mode), seed=4)
    for t, x in enumerate(movement(frames)):
        if t == 120:
            model.reset_sequence()
        model.step(None if t == 90 else x)
    return model


def same_state(a, b):
    assert a.neuron_counts == b.neuron_counts
    for name in a.layer_names:
        na, nb = getattr(a, name), getattr(b, name)
        np.testing.assert_array_equal(na.weights, nb.weights)
        np.testing.assert_array_equal(na.counters, nb.counters)
        np.testing.assert_array_equal(na.edge_array(), nb.edge_array())
    assert json.dumps(a.errors()) == json.dumps(b.errors())


@pytest.mark.parametrize("cls, mode", [(Hierarchy, "recursive"), (Hierarchy, "vector"), (FlatPredictor, "vector")])
def test_model_loaded_mid_stream_continues_bit_for_bit(tmp_path, cls, mode):
    model = trained(cls, mode)
    path = tmp_path / "model.npz"
    model.save(path)
    twin = cls.load(path)
    same_state(model, twin)
    np.testing.assert_array_equal(model.predict(), twin.predict())
    for t, x in enumerate(movement(200, offset=250)):
        x = None if t == 50 else x
        a, b = model.step(x), twin.step(x)
        assert (a is None and b is None) or np.array_equal(a, b)
    same_state(model, twin)


def test_layers_are_saved_in_the_gwr_state_format(tmp_path):
    """Each layer is stored as its GWR.state (arrays + header values); a header without them, or
    one that contradicts the parameters, is refused."""
    from gwr_predictor.learning.gwr import GWR

    model = trained()
    header, arrays = model.state()
    for name in model.layer_names:
        own = getattr(model, name).state()
        assert header[name] == {k: v for k, v in own.items() if k not in GWR.STATE_ARRAYS}
        for a in GWR.STATE_ARRAYS:
            np.testing.assert_array_equal(arrays[f"{name}.{a}"], own[a])
    older = tmp_path / "older.npz"
    write_checkpoint(older, model.kind, {k: v for k, v in header.items() if k != "gwr2"}, arrays)
    with pytest.raises(LearningError, match="missing value 'gwr2'"):
        Hierarchy.load(older)
    header["gwr2"]["match_dim"] -= 1  # a header that contradicts the parameters
    bad = tmp_path / "bad.npz"
    write_checkpoint(bad, model.kind, header, arrays)
    with pytest.raises(LearningError, match=r"layer gwr2 has match_dim"):
        Hierarchy.load(bad)


def test_random_state_and_frozen_layers_survive(tmp_path):
    model = trained()
    model.freeze_layers(("gwr1",))
    model.save(tmp_path / "m.npz")
    twin = Hierarchy.load(tmp_path / "m.npz")
    assert twin.frozen_layers == ("gwr1",)
    model.reset_layer("pgwr")
    twin.reset_layer("pgwr")
    np.testing.assert_array_equal(model.pgwr.weights, twin.pgwr.weights)


def test_file_is_an_npz_with_a_versioned_json_header(tmp_path):
    trained(frames=30).save(tmp_path / "m.npz")
    with np.load(tmp_path / "m.npz") as npz:
        header = json.loads(npz["__header__"].tobytes())
        assert {"gwr1.weights", "pgwr.edges", "win1.rows", "regs"} <= set(npz.files)
    assert (header["magic"], header["kind"], header["format_version"]) == (MAGIC, "Hierarchy", FORMAT_VERSION)
    assert HierarchyParams.from_flat(header["params"]) == HierarchyParams()


def test_overwrite_leaves_only_the_checkpoint(tmp_path):
    model = trained(frames=30)
    model.save(tmp_path / "m.npz")
    model.save(tmp_path / "m.npz")
    assert os.listdir(tmp_path) == ["m.npz"]


def test_failed_write_keeps_the_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = tmp_path / "m.npz"
    old = trained(frames=30)
    old.save(path)

    def disk_full(*args, **kwargs):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(checkpoint.np, "savez", disk_full)
    with pytest.raises(LearningError, match=r"m\.npz.*No space left"):
        trained(frames=60).save(path)
    assert os.listdir(tmp_path) == ["m.npz"]
    monkeypatch.undo()
    assert Hierarchy.load(path).errors()["steps"] == 30


def test_unwritable_destination_names_the_folder(tmp_path):
    with pytest.raises(LearningError, match="no_such_dir"):
        trained(frames=10).save(tmp_path / "no_such_dir" / "m.npz")


def _rewrite(path, header_change=None, drop=None):
    header, arrays = read_checkpoint(path, "Hierarchy")
    header.update(header_change or {})
    for name in drop or ():
        arrays.pop(name)
    meta = {k: v for k, v in header.items() if k not in ("magic", "kind", "format_version")}
    write_checkpoint(path, "Hierarchy", meta, arrays)
    if header_change and "format_version" in header_change:  # write_checkpoint stamps the current one
        with np.load(path) as npz:
            members = {k: npz[k] for k in npz.files}
        members["__header__"] = np.frombuffer(json.dumps(header).encode(), np.uint8)
        np.savez(path, **members)


@pytest.fixture
def saved(tmp_path):
    path = tmp_path / "model.npz"
    trained(frames=40).save(path)
    return path


def test_missing_file(tmp_path):
    with pytest.raises(LearningError, match=r"nothing\.npz: no such checkpoint"):
        Hierarchy.load(tmp_path / "nothing.npz")


def test_corrupt_file(saved):
    saved.write_bytes(np.random.default_rng(0).bytes(5000))
    with pytest.raises(LearningError, match=r"model\.npz: not a readable checkpoint"):
        Hierarchy.load(saved)


def test_truncated_file(saved):
    saved.write_bytes(saved.read_bytes()[: saved.stat().st_size // 2])
    with pytest.raises(LearningError, match=r"model\.npz: not a readable checkpoint"):
        Hierarchy.load(saved)


def test_npz_that_is_not_a_checkpoint(tmp_path):
    path = tmp_path / "other.npz"
    np.savez(path, a=np.zeros(3))
    with pytest.raises(LearningError, match=r"other\.npz: no '__header__'"):
        Hierarchy.load(path)


def test_other_format_version(saved):
    _rewrite(saved, {"format_version": FORMAT_VERSION + 1})
    with pytest.raises(LearningError, match=rf"format_version {FORMAT_VERSION + 1} is not supported"):
        Hierarchy.load(saved)


def test_other_kind(tmp_path):
    path = tmp_path / "flat.npz"
    trained(FlatPredictor, frames=20).save(path)
    with pytest.raises(LearningError, match=r"flat\.npz: holds a 'FlatPredictor', expected a 'Hierarchy'"):
        Hierarchy.load(path)


def test_missing_array(saved):
    _rewrite(saved, drop=["gwr2.edges"])
    with pytest.raises(LearningError, match=r"missing arrays \['gwr2.edges'\]"):
        Hierarchy.load(saved)


def test_weights_that_contradict_the_parameters(saved):
    _rewrite(saved, {"params": {**HierarchyParams().to_flat(), "tau1": 4}})
    with pytest.raises(LearningError, match=r"model\.npz: inconsistent checkpoint content"):
        Hierarchy.load(saved)


def test_bad_parameters_in_header(saved):
    _rewrite(saved, {"params": {**HierarchyParams().to_flat(), "gwr1.eps_b": 7.0}})
    with pytest.raises(LearningError, match=r"inconsistent checkpoint content.*eps_b"):
        Hierarchy.load(saved)


@pytest.mark.parametrize("mode", ["recursive", "vector"])
def test_beyond_the_paper_options_are_saved_and_continue_bit_for_bit(tmp_path, mode):
    params = HierarchyParams.paper(mode=mode, target="delta", readout_k=2)
    model = Hierarchy(params, seed=4)
    for t, x in enumerate(movement(200)):
        model.step(None if t == 90 else x)
    model.save(tmp_path / "m.npz")
    twin = Hierarchy.load(tmp_path / "m.npz")
    assert twin.params == params
    same_state(model, twin)
    np.testing.assert_array_equal(model.predict(), twin.predict())
    for x in movement(60, offset=200):
        np.testing.assert_array_equal(model.step(x), twin.step(x))


@pytest.mark.parametrize("version", [1, 2, 3, 4])
def test_files_of_earlier_formats_are_refused_with_a_hint(saved, version):
    _rewrite(saved, {"format_version": version})
    with pytest.raises(LearningError, match=rf"format_version {version} is not supported .*older build.*retrain"):
        Hierarchy.load(saved)
