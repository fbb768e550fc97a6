"""Checkpoints against hostile files and careless set-ups: every unreadable file is a LearningError
(so the learner moves it aside and starts fresh), one checkpoint path serves one learner at a time
(a lock beside it), a symlinked checkpoint is written through, and the duplicate-instance detector
does not stop a node on a stranger's word."""

import copy
import io
import json
import math
import os
import signal
import stat
import struct
import zipfile

import numpy as np
import pytest
from ros_harness import Probe
from test_node_bad_input import FAST

from gwr_predictor.default_predictor.gate import inner_model
from gwr_predictor.errors import GwrPredictorError
from gwr_predictor.learning import checkpoint as ckpt
from gwr_predictor.learning.checkpoint import (
    FORMAT_VERSION,
    HEADER_KEY,
    MAGIC,
    looks_like_checkpoint,
    read_checkpoint,
    set_aside,
    write_checkpoint,
)
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.learning.hierarchy import Hierarchy
from gwr_predictor.learning.params import HierarchyParams
from gwr_predictor.nodes import messages
from gwr_predictor.nodes.messages import DiagnosticArray
from gwr_predictor.nodes.qos import status_qos
from gwr_predictor.registry import DEFAULT_PREDICTOR, load_predictor, make_predictor


def _npy(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, array)
    return buf.getvalue()


def _header_member(header: object) -> bytes:
    return _npy(np.frombuffer(json.dumps(header).encode() if not isinstance(header, bytes) else header, np.uint8))


GOOD_HEADER = {"magic": MAGIC, "kind": "Hierarchy", "format_version": FORMAT_VERSION}


def _zip(path, members: dict[str, bytes], deflate: tuple[str, ...] = ()) -> None:
    """A checkpoint-like zip (header first), `deflate` members compressed."""
    with zipfile.ZipFile(path, "w") as zf:
        for name, data in members.items():
            zf.writestr(name + ".npy", data, zipfile.ZIP_DEFLATED if name in deflate else zipfile.ZIP_STORED)


def deflated_bad_bits(path) -> None:
    """A deflated member whose compressed bytes are garbage: zlib fails while inflating it."""
    data = _npy(np.arange(4000, dtype=np.float64))
    _zip(path, {HEADER_KEY: _header_member(GOOD_HEADER), "xbuf": data}, deflate=("xbuf",))
    with zipfile.ZipFile(path) as zf:
        info = zf.getinfo("xbuf.npy")
    raw = bytearray(path.read_bytes())
    name_len, extra_len = int.from_bytes(raw[info.header_offset + 26:info.header_offset + 28], "little"), \
        int.from_bytes(raw[info.header_offset + 28:info.header_offset + 30], "little")
    start = info.header_offset + 30 + name_len + extra_len
    raw[start:start + info.compress_size] = b"\xff" * info.compress_size  # invalid block type
    path.write_bytes(bytes(raw))


def deeply_nested_header(path) -> None:
    """Header JSON nested 100,000 deep: the parser's recursion limit."""
    _zip(path, {HEADER_KEY: _header_member(b"[" * 100_000 + b"]" * 100_000)})


def npy_declaring_a_terabyte(path) -> None:
    """A member whose npy header declares 10^12 float64 values but holds 80 bytes."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, "shape": (10**12,)})
    _zip(path, {HEADER_KEY: _header_member(GOOD_HEADER), "xbuf": buf.getvalue() + bytes(80)})


def npy_header_unreadable(path) -> None:
    """A member that is no npy array: its header is not even there."""
    _zip(path, {HEADER_KEY: _header_member(GOOD_HEADER), "xbuf": b"not an array at all"})


def header_declaring_too_much(path) -> None:
    """The header member itself declares far more bytes than it holds."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(buf, {"descr": "|u1", "fortran_order": False, "shape": (10**11,)})
    _zip(path, {HEADER_KEY: buf.getvalue() + json.dumps(GOOD_HEADER).encode()})


def many_members(path) -> None:
    """A zip of 5,000 empty members (zipfile builds about 400 bytes of directory for each)."""
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr(HEADER_KEY + ".npy", _header_member(GOOD_HEADER))
        for i in range(5_000):
            zf.writestr(f"{i}.npy", b"")


def default_with_a_nan(path) -> None:
    """The default's own file, readable and of the right kind, with one NaN in its last gate's record:
    loaded, it made every later prediction NaN."""
    model = make_predictor(DEFAULT_PREDICTOR)
    for t in range(40):
        model.step(np.sin(0.2 * t + np.arange(8)))
    header, arrays = model.state()
    arrays["ungated_gate.stats"] = arrays["ungated_gate.stats"].copy()
    arrays["ungated_gate.stats"].reshape(-1)[0] = np.nan
    write_checkpoint(path, model.kind, header, arrays)


CORRUPTIONS = {"deflated_bad_bits": deflated_bad_bits, "nested_header": deeply_nested_header,
               "npy_terabyte": npy_declaring_a_terabyte, "npy_unreadable": npy_header_unreadable,
               "header_terabyte": header_declaring_too_much}


@pytest.mark.parametrize("corrupt", CORRUPTIONS.values(), ids=CORRUPTIONS.keys())
def test_every_unreadable_checkpoint_is_a_checkpoint_error(tmp_path, corrupt):
    path = tmp_path / "model.npz"
    corrupt(path)
    assert looks_like_checkpoint(path)  # begins like ours: the learner would move it aside
    with pytest.raises(LearningError, match=r"model\.npz: ") as refused:
        read_checkpoint(path, "Hierarchy")
    assert refused.value.source == path
    with pytest.raises(LearningError, match=r"model\.npz: "):
        Hierarchy.load(path)


def test_a_zip_of_many_members_is_refused_before_its_directory_is_read(tmp_path):
    path = tmp_path / "model.npz"
    many_members(path)
    with pytest.raises(LearningError, match=r"model\.npz: 5,001 archive members exceed the limit"):
        read_checkpoint(path, "Hierarchy")


def test_a_forged_member_count_does_not_hide_a_large_directory(tmp_path):
    """The end record says 3 members; the directory holds 30,000: its size gives them away."""
    path = tmp_path / "model.npz"
    with zipfile.ZipFile(path, "w") as z:
        for i in range(30_000):
            z.writestr(f"m{i}.npy", b"")
    data = bytearray(path.read_bytes())
    end = data.rfind(b"PK\x05\x06")
    struct.pack_into("<HH", data, end + 8, 3, 3)
    path.write_bytes(bytes(data))
    with pytest.raises(LearningError, match=r"archive members exceed the limit"):
        read_checkpoint(path, "Hierarchy")


def test_a_header_nested_beyond_the_bound_is_refused_before_parsing(tmp_path):
    path = tmp_path / "model.npz"
    nested: object = 1
    for _ in range(100):
        nested = [nested]
    _zip(path, {HEADER_KEY: _header_member({**GOOD_HEADER, "x": nested})})
    with pytest.raises(LearningError, match=r"model\.npz: header nested \d+ deep"):
        read_checkpoint(path, "Hierarchy")


def test_brackets_inside_header_strings_do_not_count_as_nesting(tmp_path):
    path = tmp_path / "model.npz"
    model = Hierarchy(HierarchyParams.paper())
    header, arrays = model.state()
    header["note"] = "[[[[{{{{" * 100 + '\\"[[['
    write_checkpoint(path, model.kind, header, arrays)
    assert read_checkpoint(path, "Hierarchy")[0]["note"] == header["note"]


# --- symlinks: written through, never replaced -----------------------------------------------------


def test_a_symlinked_checkpoint_is_written_through_and_keeps_its_mode(tmp_path):
    store = tmp_path / "store"
    store.mkdir()
    target = store / "real.npz"
    Hierarchy(HierarchyParams.paper(), seed=1).save(target)
    target.chmod(0o640)
    link = tmp_path / "model.npz"
    link.symlink_to(target)
    model = Hierarchy(HierarchyParams.paper(), seed=2)
    model.step(np.zeros(8))
    model.save(link)
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert stat.S_IMODE(target.stat().st_mode) == 0o640
    assert Hierarchy.load(target).frames_seen == 1  # the target holds the new state
    assert sorted(p.name for p in store.iterdir()) == ["real.npz"]  # temp file was beside the target


def test_a_dangling_symlink_creates_its_target(tmp_path):
    target = tmp_path / "store" / "real.npz"
    target.parent.mkdir()
    link = tmp_path / "model.npz"
    link.symlink_to(target)
    Hierarchy(HierarchyParams.paper()).save(link)
    assert link.is_symlink() and target.is_file()


def test_a_new_checkpoint_gets_the_umask_default_mode(tmp_path):
    old = os.umask(0o027)
    try:
        Hierarchy(HierarchyParams.paper()).save(tmp_path / "m.npz")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "m.npz").stat().st_mode) == 0o640


def test_a_corrupt_symlinked_checkpoint_is_moved_aside_beside_its_target(tmp_path):
    target = tmp_path / "store" / "real.npz"
    target.parent.mkdir()
    target.write_bytes(b"PK\x03\x04" + bytes(100))
    link = tmp_path / "model.npz"
    link.symlink_to(target)
    aside = set_aside(link, "now")
    assert aside == target.with_name("real.npz.corrupt-now") and aside.read_bytes()[:4] == b"PK\x03\x04"
    assert link.is_symlink() and not target.exists()


# --- the lock ---------------------------------------------------------------------------------------


def test_one_lock_per_checkpoint_path_released_on_close(tmp_path):
    path = tmp_path / "model.npz"
    first = ckpt.CheckpointLock(path)
    with pytest.raises(LearningError, match=rf"model\.npz is in use by process {os.getpid()}") as locked:
        ckpt.CheckpointLock(path)
    assert locked.value.locked and locked.value.source == path
    link = tmp_path / "link.npz"
    link.symlink_to(path)
    with pytest.raises(LearningError) as locked:  # another name of the same file
        ckpt.CheckpointLock(link)
    assert locked.value.locked
    first.release()
    first.release()  # idempotent
    ckpt.CheckpointLock(path).release()
    assert not any(p.name.endswith(".tmp") for p in tmp_path.iterdir())


# --- real processes -----------------------------------------------------------------------------------


@pytest.mark.ros
@pytest.mark.parametrize("corrupt", [deflated_bad_bits, npy_declaring_a_terabyte, default_with_a_nan],
                         ids=["deflate", "npy", "nan"])
def test_the_learner_moves_any_unreadable_checkpoint_aside_and_starts_fresh(ros, tmp_path, corrupt):
    checkpoint = tmp_path / "model.npz"
    corrupt(checkpoint)
    bad = checkpoint.read_bytes()
    diagnostics = ros.diagnostics
    learner = ros.start_ready("arm_predictor", params={**FAST, "checkpoint": str(checkpoint)})
    (aside,) = tmp_path.glob("model.npz.corrupt-*")
    assert aside.read_bytes() == bad
    assert diagnostics["/arm_predictor"]["checkpoint.corrupt_moved_aside"] == "1"
    code, _ = learner.stop(signal.SIGINT)
    assert code == 0
    assert inner_model(load_predictor(DEFAULT_PREDICTOR, checkpoint)).frames_seen == 0


@pytest.mark.ros
def test_a_second_learner_on_the_same_checkpoint_refuses_to_start(ros, tmp_path):
    checkpoint = tmp_path / "model.npz"
    make_predictor(DEFAULT_PREDICTOR).save(checkpoint)
    diagnostics = ros.diagnostics
    first = ros.start("arm_predictor", label="first", params={**FAST, "checkpoint": str(checkpoint)})
    ros.wait_for_node(diagnostics, "/arm_predictor", timeout=60)
    # another namespace: the duplicate detector does not apply, only the checkpoint is shared
    code, output = ros.run("arm_predictor", label="second", namespace="/other", timeout=60,
                           params={**FAST, "checkpoint": str(checkpoint)})
    assert code == 1, output
    lines = [line for line in output.splitlines() if "in use by process" in line]
    assert len(lines) == 1 and str(checkpoint) in lines[0] and str(first.popen.pid) in lines[0], output
    assert "ready" not in output
    assert first.running()
    ros.kill(first)  # a crash: the OS releases the lock, so a restart is not blocked
    again = ros.start("arm_predictor", label="again", params={**FAST, "checkpoint": str(checkpoint)})
    ros.wait_for_log(again, "ready", timeout=60)
    code, _ = again.stop(signal.SIGINT)
    assert code == 0


@pytest.mark.ros
def test_a_stranger_taking_the_node_name_does_not_stop_it(ros):
    """A node named like the compensator publishing statuses of another 'instance' that claims to have
    started first, but with no publisher on the compensator's outputs, is not a second compensator."""
    diagnostics = ros.diagnostics
    victim = ros.start("delay_compensator", params=FAST)
    ros.wait_for_node(diagnostics, "/delay_compensator", timeout=60)
    stranger = Probe(ros.domain_id, name="delay_compensator")
    try:
        pub = stranger.node.create_publisher(DiagnosticArray, "/diagnostics", status_qos())
        stranger.spin_until(lambda: pub.get_subscription_count() >= 2, 20, "subscribers of /diagnostics")
        status = messages.diagnostic_status("/delay_compensator", {"instance": "evil:1:0"}, "ok")
        for _ in range(25):  # 5 s of statuses, like a real node's
            pub.publish(messages.diagnostic_array(0.0, [status]))
            stranger.spin_for(0.1)
            ros.probe.spin_for(0.1)
        ros.probe.spin_for(0.5)
        assert victim.running(), victim.output()
        assert "stopping this one" not in victim.output()
        assert int(diagnostics["/delay_compensator"]["duplicate.unconfirmed"]) >= 1  # noticed, counted, ignored
    finally:
        stranger.close()
    code, _ = victim.stop(signal.SIGINT)
    assert code == 0


@pytest.mark.ros
def test_a_second_node_of_the_same_name_stops_itself_and_the_first_runs_on(ros):
    """Two compensators of one name on one domain: the one that started later sees the first's statuses
    and its endpoints in the graph, and stops with the reason; the first goes on."""
    diagnostics = ros.diagnostics
    first = ros.start("delay_compensator", label="first", params=FAST)
    ros.wait_for_node(diagnostics, "/delay_compensator", timeout=60)
    code, output = ros.run("delay_compensator", label="second", params=FAST, timeout=60)
    assert code == 1, output
    assert "another /delay_compensator (instance" in output and "stopping this one" in output, output
    assert first.running() and "stopping this one" not in first.output()
    code, _ = first.stop(signal.SIGINT)
    assert code == 0


def test_a_state_a_network_refuses_is_a_checkpoint_error_naming_its_source():
    # the network's own refusal (NaN weights) is rewrapped to name the file; errors that already name
    # one (a missing array) pass through as they are
    model = Hierarchy(HierarchyParams(), seed=0)
    header, arrays = model.state()
    arrays["gwr1.weights"] = arrays["gwr1.weights"].copy()
    arrays["gwr1.weights"][0, 0] = np.nan
    with pytest.raises(LearningError, match=r"^saved\.npz: inconsistent checkpoint content: .*NaN"):
        Hierarchy.from_state(header, arrays, "saved.npz")
    del arrays["xbuf"]
    with pytest.raises(LearningError, match=r"^saved\.npz: missing arrays \['xbuf'\]$") as missing:
        Hierarchy.from_state(header, arrays, "saved.npz")
    assert missing.value.source == "saved.npz" and not missing.value.kind_mismatch


@pytest.mark.parametrize("name", ["rls_ar", "linear", "hierarchy", "gated_llm_gwr", DEFAULT_PREDICTOR])
def test_a_nan_anywhere_in_a_checkpoint_is_refused_or_changes_nothing(tmp_path, name):
    """A learner never holds NaN or inf where it learns, so a file that does is corrupt: loaded, one
    such value spread for good (a NaN in the default's last gate made every prediction NaN, one in a
    snippet memory's keys switched its recognition off). Every float array of the file in turn gets a
    NaN: the load is refused naming the array, or (where NaN means "none yet") the model continues
    exactly as the intact file's does."""
    x = np.sin(np.arange(260)[:, None] * 0.25 + np.arange(8)) * 0.6
    model = make_predictor(name)
    for f in x[:200]:
        model.step(f)
    header, arrays = model.state()
    intact = type(model).from_state(header, arrays)
    expected = [intact.step(f) for f in x[200:]]
    spoilt_states = []
    for key, array in arrays.items():
        finite = np.flatnonzero(np.isfinite(array)) if array.dtype.kind == "f" else ()
        if len(finite):
            spoilt = dict(arrays)
            spoilt[key] = array.copy()
            spoilt[key].reshape(-1)[finite[0]] = np.nan
            spoilt_states.append((key, header, spoilt))
    for path in _float_leaves(header):
        spoilt_header = copy.deepcopy(header)
        _set_leaf(spoilt_header, path, math.nan)
        spoilt_states.append(("header " + ".".join(map(str, path)), spoilt_header, arrays))
    refused = 0
    for what, spoilt_header, spoilt_arrays in spoilt_states:
        try:
            loaded = type(model).from_state(spoilt_header, spoilt_arrays, "spoilt.npz")
        except GwrPredictorError as exc:  # a LearningError; a baseline's own class for the baselines
            assert str(exc).startswith("spoilt.npz: "), what
            refused += 1
            continue
        for f, want in zip(x[200:], expected, strict=True):
            np.testing.assert_array_equal(loaded.step(f), want, err_msg=f"a NaN in {what} was learned from")
    assert refused > 0


def _float_leaves(tree, path=()):
    """Paths to the float leaves of a JSON-like header."""
    items = tree.items() if isinstance(tree, dict) else enumerate(tree) if isinstance(tree, list) else ()
    for k, v in items:
        if isinstance(v, float) and math.isfinite(v):
            yield (*path, k)
        else:
            yield from _float_leaves(v, (*path, k))


def _set_leaf(tree, path, value):
    for k in path[:-1]:
        tree = tree[k]
    tree[path[-1]] = value


@pytest.mark.ros
def test_the_learner_stops_on_a_readable_checkpoint_of_another_predictor_and_leaves_it(ros, tmp_path):
    checkpoint = tmp_path / "model.npz"
    make_predictor("hierarchy", HierarchyParams(), seed=0).save(checkpoint)
    saved = checkpoint.read_bytes()
    code, output = ros.run("arm_predictor", params={**FAST, "checkpoint": str(checkpoint),
                                                    "predictor": DEFAULT_PREDICTOR}, timeout=60)
    assert code == 1, output
    assert "does not fit parameter predictor" in output and "ready" not in output
    assert checkpoint.read_bytes() == saved
    assert not list(tmp_path.glob("model.npz.corrupt-*"))
