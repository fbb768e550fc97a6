"""NaoSimulator: position control under velocity limits, separate clients, time keeping, pictures."""

import numpy as np
import pybullet
import pytest
from PIL import Image

from gwr_predictor.robot import nao
from gwr_predictor.robot.errors import RobotError
from gwr_predictor.robot.pybullet_nao import NaoSimulator, contact_sheet, save_png

REST = np.array([1.4, 0.2, -1.2, -0.5, 1.4, -0.2, 1.2, 0.5])


def trajectory(t: float) -> np.ndarray:
    return REST + np.array([0.5 * np.sin(np.pi * t), 0.2 * np.sin(0.6 * np.pi * t), 0.4 * np.sin(0.8 * np.pi * t),
                            -0.3 * np.sin(0.8 * np.pi * t), 0.5 * np.sin(np.pi * t), -0.2 * np.sin(0.6 * np.pi * t),
                            -0.4 * np.sin(0.8 * np.pi * t), 0.3 * np.sin(0.8 * np.pi * t)])


def test_simulator_tracks_a_commanded_trajectory():
    with NaoSimulator() as sim:
        sim.reset(REST)
        errors = []
        for t in np.arange(0.0, 3.0, 0.01):
            sim.command(trajectory(t))
            sim.step(0.01)
            errors.append(sim.joint_positions() - trajectory(t))
    rmse = np.sqrt(np.mean(np.square(errors[50:]), axis=0))
    assert rmse.max() < 0.05, rmse


def test_joint_speed_stays_within_nao_velocity_limits():
    with NaoSimulator() as sim:
        sim.reset(REST)
        sim.command(REST - np.array([2.5, 0.0, 2.0, 0.0, 2.5, 0.0, -2.0, 0.0]))
        speeds = []
        for _ in range(60):
            sim.step(0.005)
            speeds.append(np.abs(sim.joint_velocities()))
    limits = np.array([nao.VELOCITY_LIMITS[n] for n in nao.ARM_JOINTS])
    peak = np.max(speeds, axis=0)
    assert np.all(peak <= limits * 1.02), (peak, limits)
    assert peak[0] > 0.9 * limits[0]  # the big shoulder move does run at its limit


def test_two_simulators_keep_separate_clients():
    with NaoSimulator() as a, NaoSimulator() as b:
        assert a.client != b.client
        a.reset(REST)
        b.reset(np.array([0.0, 0.5, 0.0, -1.0, 0.0, -0.5, 0.0, 1.0]))
        a.step(0.2)
        np.testing.assert_allclose(b.joint_positions(), [0.0, 0.5, 0.0, -1.0, 0.0, -0.5, 0.0, 1.0], atol=1e-9)
        client_a = a.client
    assert not pybullet.isConnected(physicsClientId=client_a)


def test_closed_simulator_refuses_use():
    sim = NaoSimulator()
    sim.close()
    sim.close()  # idempotent
    with pytest.raises(RobotError, match="closed"):
        sim.joint_positions()


def test_step_carries_the_remainder_so_time_follows_requests():
    with NaoSimulator(time_step=1.0 / 240.0) as sim:
        steps = sum(sim.step(0.01) for _ in range(100))
        assert sim.t == pytest.approx(1.0)
        assert steps == 240


def test_command_by_name_moves_only_that_joint_and_stops_at_its_limit():
    with NaoSimulator() as sim:
        sim.reset(REST)
        sim.command({"LElbowRoll": 0.5})  # outside [-1.54, -0.035]: the URDF's joint limit stops it
        sim.step(0.5)
        got = sim.joint_positions()
    expected = REST.copy()
    expected[3] = nao.JOINT_LIMITS["LElbowRoll"][1]
    np.testing.assert_allclose(got, expected, atol=2e-3)


def test_command_rejects_unknown_joints_and_wrong_shapes():
    with NaoSimulator() as sim:
        with pytest.raises(RobotError, match="HeadYaw"):
            sim.command({"HeadYaw": 0.1})
        with pytest.raises(RobotError, match="shape"):
            sim.command(np.zeros(5))


def test_render_shows_the_arm_moving(tmp_path):
    with NaoSimulator() as sim:
        sim.reset(REST)
        down = sim.render(160, 120)
        sim.reset(np.array([-1.5, 0.3, 0.0, -0.1, -1.5, -0.3, 0.0, 0.1]))
        up = sim.render(160, 120)
    assert down.shape == (120, 160, 3) and down.dtype == np.uint8
    assert down.std() > 10  # not a blank frame
    assert np.mean(np.any(down != up, axis=2)) > 0.01  # raising the arms changes the picture
    sheet = contact_sheet([down, up, down], tmp_path / "sheet.png", columns=2, labels=["down", "up", "down"])
    with Image.open(sheet) as im:
        assert im.size == (320, 240)
    with Image.open(save_png(up, tmp_path / "up.png")) as im:
        np.testing.assert_array_equal(np.asarray(im), up)


def test_missing_urdf_is_named_in_the_error(tmp_path):
    with pytest.raises(RobotError, match=r"nope\.urdf"):
        NaoSimulator(urdf_path=tmp_path / "nope.urdf")
