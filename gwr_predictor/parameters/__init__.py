"""One parameter declared once (`spec.ParamSpec`): the learner's and the robot's dataclasses check their
fields with it, the nodes declare it as a described ROS parameter, the docs tables are made from it.
"""
