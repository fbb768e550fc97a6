"""The 8 arm angles every part exchanges (a learner's frame, a JointState's names) and the range of each.

In `joints`, below the other subpackages, because data, pipeline, robot and the learner all read them,
and the learner imports none of the others: it draws its first random neurons inside these ranges.
`robot.nao` adds the rest of the robot's facts (wrists, velocities, kinematics) and re-exports these names.
"""

from __future__ import annotations

SIDES = ("L", "R")
ARM_JOINT_SUFFIXES = ("ShoulderPitch", "ShoulderRoll", "ElbowYaw", "ElbowRoll")
#: The 8 angles of the paper, in the order used everywhere (learner vectors, JointState names).
ARM_JOINTS: tuple[str, ...] = tuple(s + j for s in SIDES for j in ARM_JOINT_SUFFIXES)

#: (lower, upper) of each arm angle in radians: the Nao's joint limits (published V4/V5 figures).
ARM_JOINT_LIMITS: dict[str, tuple[float, float]] = {
    "LShoulderPitch": (-2.08567, 2.08567),
    "LShoulderRoll": (-0.314159, 1.32645),
    "LElbowYaw": (-2.08567, 2.08567),
    "LElbowRoll": (-1.54462, -0.0349066),
    "RShoulderPitch": (-2.08567, 2.08567),
    "RShoulderRoll": (-1.32645, 0.314159),
    "RElbowYaw": (-2.08567, 2.08567),
    "RElbowRoll": (0.0349066, 1.54462),
}
