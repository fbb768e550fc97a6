"""The joints every part names: the 8 arm angles (`arm`) the learner, the robot and the messages
exchange, the 15-joint skeleton every source delivers (`skeleton`), and how many joint names an input
may carry (`names`).

Below every other subpackage (the learner draws its first neurons inside the arm's limits, the data's
sources make the skeleton the pipeline's messages carry), so that none of them imports another for a name.
"""
