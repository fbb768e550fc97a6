"""Hostile files and paths: checkpoints that declare more than they hold, lock files and outputs that are
links, YAML alias bombs, FIFOs and devices where a file is expected, MCAP files that claim a terabyte.

Each is refused at once with a one-line error naming the file (or, in a running node, counted and
logged), within bounded memory: whatever could allocate runs in a subprocess under an address-space
limit, so that the old behaviour (gigabytes, then a MemoryError traceback) fails the test instead of
the machine. The rules live in `gwr_predictor.files.user_files` (reading, writing, lock files),
`files.yaml_safe` (YAML), `gwr_predictor.pipeline.mcap_limits` and `checkpoint.check_network_sizes`.
"""

from __future__ import annotations

import io
import os
import resource
import shutil
import signal
import struct
import subprocess
import sys
import textwrap
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest
from test_node_bad_input import FAST, joint_state

from gwr_predictor.commands import cli
from gwr_predictor.files.limits import MAX_NETWORK_NEURONS
from gwr_predictor.learning.checkpoint import CheckpointLock, check_checkpoint_place
from gwr_predictor.learning.errors import LearningError
from gwr_predictor.pipeline import bag_reader
from gwr_predictor.pipeline.errors import PipelineError
from gwr_predictor.pipeline.params_file import check_params_files
from gwr_predictor.pipeline.video_files import default_suffix
from gwr_predictor.registry import make_predictor

ROOT = Path(__file__).resolve().parents[1]
SAMPLE_BAG = ROOT / "bags" / "demo_sample"
#: Address space of a subprocess that may meet a hostile file: far above what reading a small file
#: takes (python, numpy, rosbags, matplotlib: about 0.5 GB), far below what the old code asked for.
MEMORY_LIMIT = 1536 << 20


def bounded(argv: list[str], timeout: float = 30.0, memory: int = MEMORY_LIMIT) -> tuple[int, str, float]:
    """(exit code, stdout + stderr, seconds) of `argv` under an address-space limit; a run that outlives
    `timeout` (it blocked) fails the test."""
    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (memory, memory))

    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    start = time.monotonic()
    try:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=timeout, preexec_fn=limit, env=env,
                              cwd=ROOT)
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"{argv[3:]} did not end within {timeout} s (blocked?): {exc.stderr or ''!s}"[-2000:])
    return done.returncode, done.stdout + done.stderr, time.monotonic() - start


def command(*args: str, timeout: float = 30.0) -> tuple[int, str]:
    """`gwr-predictor ARGS` in a bounded subprocess: (exit code, output)."""
    code, output, _ = bounded([sys.executable, "-m", "gwr_predictor", *map(str, args)], timeout)
    return code, output


def refusal(imports: str, call: str, error: str) -> str:
    """The message of the `error` that `call` raises in a bounded subprocess, within 20 s."""
    script = f"{imports}\ntry:\n    {call}\nexcept {error} as exc:\n    print('refused:', exc)\n"
    code, output, seconds = bounded([sys.executable, "-c", script])
    assert code == 0 and "refused:" in output and seconds < 20, output[-3000:]
    return output


def one_line_error(code: int, output: str, *needles: str) -> None:
    """A refusal: non-zero exit, no traceback, and one error line that says each of `needles`."""
    assert code != 0 and "Traceback" not in output and "MemoryError" not in output, output[-3000:]
    lines = [line for line in output.splitlines() if "error" in line.lower()]
    assert lines and all(n in lines[-1] for n in needles), output[-3000:]


def fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


# --- 1: checkpoints that declare a huge network -------------------------------------------------------


def npz_member(array: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array(buf, array, allow_pickle=False)
    return buf.getvalue()


def huge_network_checkpoint(path: Path, neurons: int = 40_000) -> Path:
    """A real hierarchy checkpoint whose first layer (max_neurons unlimited, as by default) claims
    `neurons` neurons: zeros, deflated to a few kB."""
    make_predictor("hierarchy").save(path)
    with zipfile.ZipFile(path) as zf:
        members = {info.filename: zf.read(info) for info in zf.infolist()}
    dim = np.load(io.BytesIO(members["gwr1.weights.npy"])).shape[1]
    members["gwr1.weights.npy"] = npz_member(np.zeros((neurons, dim)))
    members["gwr1.counters.npy"] = npz_member(np.ones(neurons))
    members["gwr1.edges.npy"] = npz_member(np.zeros((0, 3), dtype=np.int64))
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in members.items():  # the header first, as in every checkpoint
            zf.writestr(name, data)
    return path


def test_a_checkpoint_declaring_a_huge_network_is_refused_before_anything_is_allocated(tmp_path):
    path = huge_network_checkpoint(tmp_path / "model.npz")
    assert path.stat().st_size < 100_000
    output = refusal("from gwr_predictor.learning.errors import LearningError\n"
                     "from gwr_predictor.registry import load_predictor",
                     f"load_predictor('hierarchy', {str(path)!r})", "LearningError")
    assert "40,000 neurons" in output and f"{MAX_NETWORK_NEURONS:,}" in output, output
    angles = tmp_path / "angles.csv"
    from gwr_predictor.data.angle_files import save_angles_csv
    save_angles_csv(angles, np.arange(30) * 0.1, np.zeros((30, 8)))
    code, output = command("evaluate", angles, "--checkpoint", path, "--methods", "hierarchy", "--no-progress")
    one_line_error(code, output, "40,000 neurons")


@pytest.mark.ros
def test_the_learner_counts_a_memory_error_in_a_frame_goes_on_and_keeps_what_it_learned(tmp_path, monkeypatch):
    import rclpy
    from ros_harness import allocate_domain_id, release_domain_id

    from gwr_predictor.default_predictor.gate import inner_model
    from gwr_predictor.nodes.arm_predictor import ArmPredictorNode
    from gwr_predictor.registry import load_predictor

    checkpoint = tmp_path / "model.npz"
    domain = allocate_domain_id()
    rclpy.init(args=["--ros-args", "-p", f"checkpoint:={checkpoint}", "-p", "predictor:=hierarchy"],
               domain_id=domain)
    try:
        node = ArmPredictorNode()
        now = time.time() - 10.0
        rng = np.random.default_rng(0)
        pose = np.array([1.2, 0.2, -1.0, -0.5, 1.2, -0.2, 1.0, 0.5])
        for k in range(20):
            node.on_angles(joint_state(now + 0.1 * k, pose + 0.05 * rng.standard_normal(8)))
        learned = inner_model(node.model).frames_seen

        def out_of_memory(*args, **kwargs):
            raise MemoryError("a network that cannot double")

        with monkeypatch.context() as m:
            m.setattr(node.model, "step", out_of_memory)
            node.on_angles(joint_state(now + 2.0, pose))  # the old node died here
        assert node.counters.get("frames.out_of_memory") == 1
        node.on_angles(joint_state(now + 2.1, pose))
        assert inner_model(node.model).frames_seen > learned
        node.on_shutdown()
        assert inner_model(load_predictor("hierarchy", checkpoint)).frames_seen == inner_model(node.model).frames_seen
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
        release_domain_id(domain)


# --- 2, 8: the checkpoint's lock file and a symlink loop ----------------------------------------------


@pytest.mark.parametrize("link", ["symlink", "hard link"])
def test_the_checkpoint_lock_never_writes_through_a_link(tmp_path, link):
    victim = tmp_path / "thesis.txt"
    victim.write_text("three years of work")
    folder = tmp_path / "models"
    folder.mkdir()
    lock = folder / ".model.npz.lock"
    if link == "symlink":
        lock.symlink_to(victim)
    else:
        os.link(victim, lock)
    with pytest.raises(LearningError, match=r"\.model\.npz\.lock: is a (symlink|hard link)"):
        CheckpointLock(folder / "model.npz")
    assert victim.read_text() == "three years of work"


def test_a_symlink_loop_as_checkpoint_is_refused_at_start(tmp_path):
    (tmp_path / "a.npz").symlink_to(tmp_path / "b.npz")
    (tmp_path / "b.npz").symlink_to(tmp_path / "a.npz")
    with pytest.raises(LearningError, match=r"a\.npz: cannot be used as a checkpoint: a symlink loop"):
        check_checkpoint_place(tmp_path / "a.npz")


# --- 3, 4, 10 (minor): params files ---------------------------------------------------------------


def alias_bomb(path: Path, levels: int = 9, width: int = 9) -> Path:
    """The billion laughs as a params file: under 1 kB, `width ** levels` parameters once its nested
    mappings are flattened into parameter names."""
    def mapping(value: str) -> str:
        return "{" + ", ".join(f"k{i}: {value}" for i in range(width)) + "}"

    lines = ["arm_predictor:", "  ros__parameters:", f"    l0: &l0 {mapping('lol')}"]
    lines += [f"    l{k}: &l{k} {mapping(f'*l{k - 1}')}" for k in range(1, levels)]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_yaml_alias_bomb_is_refused_before_it_expands(tmp_path):
    bomb = alias_bomb(tmp_path / "bomb.yaml")
    assert bomb.stat().st_size < 1200
    output = refusal("from gwr_predictor.pipeline.errors import PipelineError\n"
                     "from gwr_predictor.pipeline.params_file import check_params_files",
                     f"check_params_files(['node', '--ros-args', '--params-file', {str(bomb)!r}])", "PipelineError")
    assert "alias '*l0'" in output, output
    code, output = command("pretrain", "--params-file", bomb, "-o", tmp_path / "model.npz", "--quiet")
    one_line_error(code, output, "bomb.yaml", "alias")
    assert not (tmp_path / "model.npz").exists()


@pytest.mark.ros
@pytest.mark.parametrize("node", ["arm_predictor", "hri_bodies"])
def test_nodes_refuse_a_yaml_alias_bomb_at_once(ros, tmp_path, node):
    bomb = alias_bomb(tmp_path / "bomb.yaml")
    start = time.monotonic()
    code, output = ros.run(node, timeout=30, params_file=bomb, executable=shutil.which("prlimit"),
                           extra_args=[f"--as={MEMORY_LIMIT * 2}", ros.executable(node)])
    assert code == 2 and "alias" in output and "Traceback" not in output, output[-3000:]
    assert time.monotonic() - start < 20


@pytest.mark.parametrize("kind", ["fifo", "device", "too_large"])
def test_pretrain_checks_its_params_file_as_the_nodes_do(tmp_path, kind):
    if kind == "fifo":
        params, needle = fifo(tmp_path / "params.yaml"), "FIFO"
    elif kind == "device":
        params, needle = Path("/dev/zero"), "character device"
    else:
        params, needle = tmp_path / "params.yaml", "too large"
        params.write_text("arm_predictor:\n  ros__parameters:\n    seed: 1\n" + "# padding\n" * 150_000)
    code, output = command("pretrain", "--params-file", params, "-o", tmp_path / "model.npz", "--quiet",
                           timeout=20)
    one_line_error(code, output, str(params), needle)
    with pytest.raises(PipelineError, match=needle):
        check_params_files(["node", "--ros-args", "--params-file", str(params)])


# --- 5, 6, 9: bags ---------------------------------------------------------------------------------


def copy_bag(tmp_path: Path) -> Path:
    bag = tmp_path / "bag"
    shutil.copytree(SAMPLE_BAG, bag)
    return bag


def forge_first_chunk_index(mcap: Path, compressed_size: int) -> None:
    """Change the 8 bytes of the first chunk index's compressed size."""
    data = bytearray(mcap.read_bytes())
    at = 8
    while data[at] != 0x08:
        at += 9 + struct.unpack_from("<Q", data, at + 1)[0]
    field = at + 9 + 32
    field += 4 + struct.unpack_from("<I", data, field)[0] + 8  # message index offsets, their length
    field += 4 + struct.unpack_from("<I", data, field)[0]  # compression
    struct.pack_into("<Q", data, field, compressed_size)
    mcap.write_bytes(bytes(data))


@pytest.mark.parametrize("bare", [False, True], ids=["bag folder", "bare mcap"])
def test_a_chunk_index_claiming_a_terabyte_is_refused_before_reading(tmp_path, bare):
    bag = copy_bag(tmp_path)
    forge_first_chunk_index(bag / "bag.mcap", 1 << 40)
    target = bag / "bag.mcap" if bare else bag
    output = refusal("from gwr_predictor.pipeline import bag_reader\n"
                     "from gwr_predictor.pipeline.errors import PipelineError",
                     f"list(bag_reader.read_bag({str(target)!r}))", "PipelineError")
    assert "1,099,511,627,776 compressed" in output, output
    if not bare:
        for args in (["report", bag, "--out", tmp_path / "out"], ["render", bag, "-o", tmp_path / "v.gif",
                                                                  "--no-progress"]):
            code, output = command(*args)
            one_line_error(code, output, "bag.mcap", "chunk index")
        assert not (tmp_path / "out").exists() and not (tmp_path / "v.gif").exists()


def test_a_record_longer_than_the_file_is_refused_before_reading(tmp_path):
    mcap = copy_bag(tmp_path) / "bag.mcap"
    data = bytearray(mcap.read_bytes())
    struct.pack_into("<Q", data, 9, 1 << 40)  # the header record's length
    mcap.write_bytes(bytes(data))
    with pytest.raises(PipelineError,
                       match=r"record 0x01 at byte 8 declares 1,099,511,627,776 bytes, past the end"):
        bag_reader.bag_info(mcap)


@pytest.mark.ros
def test_a_fifo_in_a_bag_is_refused_at_once_by_every_reader(ros, tmp_path):
    bag = copy_bag(tmp_path)
    (bag / "bag.mcap").unlink()
    fifo(bag / "bag.mcap")
    for name in ("report", "latency"):
        code, output = command(name, bag, "--out", tmp_path / "out", timeout=20)
        one_line_error(code, output, "bag.mcap", "FIFO")
    start = time.monotonic()
    code, output = ros.run("bag_player", timeout=30, params={**FAST, "bag": str(bag)})
    assert code == 1 and "FIFO" in output and "Traceback" not in output, output[-3000:]
    assert time.monotonic() - start < 20


@pytest.mark.ros
def test_a_signal_stops_a_node_whose_start_blocks(tmp_path):
    """Whatever a node's start waits for (a FIFO no one writes, a hung network file system), SIGINT
    and SIGTERM end it: before it runs there is nothing to save."""
    from ros_harness import allocate_domain_id, release_domain_id, ros_env

    blocked = fifo(tmp_path / "never_written")
    script = tmp_path / "slow_node.py"
    script.write_text(textwrap.dedent(f"""
        import sys
        from gwr_predictor.nodes.pipeline_node import PipelineNode
        from gwr_predictor.nodes.runner import run_node

        class Blocked(PipelineNode):
            NODE_NAME = "blocked"

            def __init__(self):
                super().__init__(self.NODE_NAME, ())
                print("opening", flush=True)
                open({str(blocked)!r}, "rb")

        sys.exit(run_node(Blocked, ["blocked"]))
        """))
    domain = allocate_domain_id()
    try:
        for sig in (signal.SIGTERM, signal.SIGINT):
            proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                    env=ros_env(domain, tmp_path), text=True)
            assert proc.stdout is not None
            while proc.stdout.readline().strip() != "opening":
                assert proc.poll() is None, proc.stdout.read()
            time.sleep(0.3)  # inside open()
            proc.send_signal(sig)
            try:
                output, _ = proc.communicate(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                pytest.fail(f"{sig.name} did not stop a node blocked at start")
            assert proc.returncode == 0 and "received while starting" in output, output
    finally:
        release_domain_id(domain)


def test_bag_metadata_with_aliases_or_over_its_size_is_refused_before_parsing(tmp_path):
    bag = copy_bag(tmp_path)
    meta = bag / "metadata.yaml"
    text = meta.read_text()
    meta.write_text(text.replace("  duration:\n", "  duration: &span\n", 1).replace(
        "  - duration:\n      nanoseconds: 30984965707\n", "  - duration: *span\n", 1))
    assert bag_reader.bag_info(SAMPLE_BAG).message_count == 3840  # the same bag without the alias reads
    with pytest.raises(PipelineError, match=r"metadata\.yaml: YAML alias '\*span'"):
        bag_reader.bag_info(bag)
    meta.write_text(text + "# padding\n" * (bag_reader.MAX_METADATA_BYTES // 10))
    with pytest.raises(PipelineError, match=r"metadata\.yaml: 1 MB is too large for a bag's metadata\.yaml"):
        bag_reader.bag_info(bag)


# --- 7, 10: where the commands write ------------------------------------------------------------------


@pytest.mark.parametrize("place", ["symlink", "fifo"])
def test_pretrain_never_writes_through_a_symlink_nor_replaces_a_fifo(tmp_path, capsys, place):
    victim = tmp_path / "thesis.txt"
    victim.write_text("three years of work")
    out = tmp_path / "model.npz"
    if place == "symlink":
        out.symlink_to(victim)
    else:
        fifo(out)
    code = cli.main(["pretrain", "-o", str(out), "--patterns", "wave_both", "--subjects", "1", "--repetitions", "1",
                     "--epochs", "1", "--quiet"])
    err = capsys.readouterr().err
    assert code == 2 and "model.npz exists and is not a gwr_predictor checkpoint" in err, err
    assert victim.read_text() == "three years of work"
    assert out.is_symlink() if place == "symlink" else out.is_fifo()


def test_outputs_in_a_place_that_cannot_be_written_are_one_line_errors(tmp_path, capsys):
    blocked = tmp_path / "a_file"
    blocked.write_text("not a folder")
    for args in (["report", SAMPLE_BAG, "--out", blocked / "out"], ["latency", SAMPLE_BAG, "--out", "/proc/self"],
                 ["render", SAMPLE_BAG, "-o", f"/proc/self/video{default_suffix()}", "--seconds", "0:0.5",
                  "--no-progress"]):
        code = cli.main([str(a) for a in args])
        err = capsys.readouterr().err
        assert code == 1 and "cannot write the" in err and len(err.strip().splitlines()) == 1, (args, err)


def test_an_output_that_is_a_symlink_is_not_written_through(tmp_path, capsys):
    victim = tmp_path / "thesis.txt"
    victim.write_text("three years of work")
    out = tmp_path / "out"
    out.mkdir()
    (out / "latency.json").symlink_to(victim)
    assert cli.main(["latency", str(SAMPLE_BAG), "--out", str(out)]) == 1
    assert "latency.json: is a symlink" in capsys.readouterr().err
    assert victim.read_text() == "three years of work"
