"""The harness's domain ids: concurrent test runs on one machine never share a ROS domain."""

import os
import subprocess
import sys

import ros_harness
from ros_harness import ROOT, allocate_domain_id, release_domain_id

RANGE = (100, 101)  # ids no default range uses: other runs do not hold them


def allocate_in_another_run() -> int:
    """The domain id a second pytest run (another process) with the same range would get now."""
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    env["GWR_TEST_DOMAINS"] = f"{RANGE[0]}-{RANGE[1]}"
    code = "import sys; sys.path.insert(0, 'test'); import ros_harness; print(ros_harness.allocate_domain_id())"
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return int(out.stdout.split()[-1])


def test_another_run_gets_the_one_domain_this_run_does_not_hold(monkeypatch):
    monkeypatch.setenv("GWR_TEST_DOMAINS", f"{RANGE[0]}-{RANGE[1]}")
    monkeypatch.setattr(ros_harness, "_used_domains", set())
    held = [allocate_domain_id() for _ in range(RANGE[1] - RANGE[0] + 1)]
    try:
        assert sorted(held) == list(range(RANGE[0], RANGE[1] + 1))
        free = held.pop(1)
        release_domain_id(free)
        assert allocate_in_another_run() == free
    finally:
        for domain in held:
            release_domain_id(domain)
