"""ament_python packaging: `colcon build` + `ros2 run gwr_predictor <node>` on a full Jazzy install."""

import os
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "gwr_predictor"

# One console script per node (ros2 run gwr_predictor <name>) plus the library's command line.
NODES = [
    "skeleton_source",
    "angle_extractor",
    "arm_predictor",
    "delay_compensator",
    "nao_sim",
    "bag_recorder",
    "bag_player",
    "hri_bodies",
]
#: Old executable names, kept for one release: name -> the function that starts the node (with a warning).
DEPRECATED = {"gwr_hierarchy": "arm_predictor:main_gwr_hierarchy"}


def tree_data_files(root: str, dest: str) -> list[tuple[str, list[str]]]:
    """data_files entries for every file below `root`, keeping the folder structure."""
    entries = []
    for folder, _, files in os.walk(root):
        if files:
            target = os.path.join(dest, os.path.relpath(folder, root))
            entries.append((os.path.normpath(target), [os.path.join(folder, f) for f in files]))
    return entries


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=[*find_packages(include=[PACKAGE, f"{PACKAGE}.*"]), f"{PACKAGE}.nodes"],
    package_dir={f"{PACKAGE}.nodes": "nodes"},
    package_data={f"{PACKAGE}.robot": ["*.urdf"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE}/launch", glob("launch/*.launch.py")),
        (f"share/{PACKAGE}/rviz", glob("rviz/*.rviz")),
        (f"share/{PACKAGE}/urdf", ["gwr_predictor/robot/nao.urdf"]),
    ]
    + tree_data_files("bags", f"share/{PACKAGE}/bags"),
    install_requires=["setuptools", "numpy", "threadpoolctl"],
    zip_safe=True,
    maintainer="gwr_predictor maintainers",
    maintainer_email="maintainers@gwr-predictor.dev",
    description="Online GWR-hierarchy prediction of arm joint angles for robot delay compensation",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [f"{name} = {PACKAGE}.nodes.{name}:main" for name in NODES]
        + [f"{name} = {PACKAGE}.nodes.{target}" for name, target in DEPRECATED.items()]
        + [f"gwr-predictor = {PACKAGE}.commands.cli:main"],
    },
)
