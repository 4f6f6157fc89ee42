"""ament_python package `ambiegen_ros`; also a plain pip package (no ROS needed).

`colcon build --paths . ambiegen_msgs` builds it next to the interface package on a ROS machine;
`pip install .` installs the same code, its console scripts and the .msg files it needs to speak
ROS 2 over Cyclone DDS without rclpy.
"""
import runpy
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "ambiegen_ros"
# the one table of dependencies and minimum versions (stdlib only, so readable before any install)
DEPS = runpy.run_path(str(Path(__file__).resolve().parent / PACKAGE / "deps.py"))
ENTRY = runpy.run_path(str(Path(__file__).resolve().parent / PACKAGE / "entry.py"))

setup(
    name=PACKAGE,
    version="0.1.0",
    description="AmbieGen: evolutionary search for environments in which autonomous systems fail (ROS 2)",
    packages=find_packages(include=["ambiegen_ros", "ambiegen_ros.*", "sim_nodes", "sim_nodes.*"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + PACKAGE]),
        ("share/" + PACKAGE, ["package.xml"]),
        ("share/" + PACKAGE + "/launch", glob("launch/*.py")),
        ("share/" + PACKAGE + "/config", glob("config/*.yaml")),
        ("share/" + PACKAGE + "/config/nav2", glob("config/nav2/*.yaml")),
        ("share/" + PACKAGE + "/config/robots", glob("config/robots/*.yaml")),
        ("share/" + PACKAGE + "/config/nav2/fixes", glob("config/nav2/fixes/*.yaml") + glob("config/nav2/fixes/*.xml")),
        ("share/" + PACKAGE + "/config/foxglove", glob("config/foxglove/*.json")),
        # the message definitions, so the DDS backend can build the types without a ROS install
        ("share/" + PACKAGE + "/ambiegen_msgs/msg", glob("ambiegen_msgs/msg/*.msg")),
    ],
    python_requires=">=3.10",
    install_requires=DEPS["install_requires"](),  # ambiegen_ros/deps.py: pins and minimums, and why
    # ranges for users' own environments; scripts/setup.sh and CI install the versions pinned in constraints.txt
    extras_require={"test": ["pytest>=8", "pytest-random-order>=1.1", "pytest-xdist>=3.5", "hypothesis>=6.100", "mcap-ros2-support==0.6.0",
                             "mypy>=1.10",
                             # the manual in docs/ (Sphinx + MyST; test/test_docs.py builds it with -W)
                             "sphinx>=7.4,<10", "myst-parser>=4.0,<6"]},
    zip_safe=True,
    maintainer="AmbieGen-ROS team",
    maintainer_email="ambiegen-ros@example.org",
    license="MIT",
    # every script runs through ambiegen_ros/entry.py, which turns a failed dependency import into one line
    entry_points={"console_scripts": [f"{name} = {PACKAGE}.entry:{name}" for name in ENTRY["SCRIPTS"]]},
)
