"""ros2 launch ambiegen_ros campaign.launch.py problem:=robot algorithm:=nsga2 workers:=2

Starts a recorder, `workers` sim nodes of the problem and the generator (the same node set as
`ambiegen campaign` on machines without ROS). Arguments: problem, algorithm, evaluations
(0 = the paper's budget), time_budget (s, 0 = none), seed (-1 = drawn), mode
(surrogate | in_the_loop), workers, output_dir, config_file ('' = config/<problem>.yaml), profile
(fidelity profile of the generator and every sim node: replication | refined; '' = the config
file's, else replication).
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

SIM_EXECUTABLES = {"robot": "robot_sim", "vehicle": "car_sim", "thermostat": "thermostat_sim"}

ARGUMENTS = {
    "problem": ("robot", "thermostat | robot | vehicle"),
    "algorithm": ("nsga2", "ga | nsga2 | random"),
    "evaluations": ("0", "evaluation budget (0 = the paper's)"),
    "time_budget": ("0.0", "wall-clock budget in seconds (0 = none)"),
    "seed": ("-1", "random seed (-1 = drawn and recorded)"),
    "mode": ("surrogate", "surrogate | in_the_loop"),
    "workers": ("1", "number of sim nodes sharing the scenarios"),
    "output_dir": (".", "where the recorder writes <run>.mcap"),
    "config_file": ("", "run config YAML ('' = the package's config/<problem>.yaml)"),
    "profile": ("", "fidelity profile of every node: replication | refined ('' = the config file's, else replication)"),
}


def _nodes(context):
    value = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
    problem = value["problem"]
    config = value["config_file"] or os.path.join(get_package_share_directory("ambiegen_ros"), "config", f"{problem}.yaml")
    workers = int(value["workers"])
    output = os.path.join(value["output_dir"], f"ambiegen_{problem}_{value['algorithm']}.mcap")
    nodes = [
        Node(package="ambiegen_ros", executable="recorder", name="recorder", output="screen",
             parameters=[{"output": output}]),
    ]
    for k in range(workers):
        name = f"{problem}_sim_{k}"
        nodes.append(Node(package="ambiegen_ros", executable=SIM_EXECUTABLES[problem], name=name, output="screen",
                          parameters=[{"worker_id": name, "config_file": config, "profile": value["profile"],
                                       "min_result_subscribers": 2}]))
    nodes.append(Node(
        package="ambiegen_ros", executable="generator", name="generator", output="screen",
        parameters=[{
            "problem": problem,
            "algorithm": value["algorithm"],
            "evaluations": int(value["evaluations"]),
            "time_budget": float(value["time_budget"]),
            "seed": int(value["seed"]),
            "mode": value["mode"],
            "config_file": config,
            "profile": value["profile"],
            "min_subscribers": workers + 1,
        }],
    ))
    return nodes


def generate_launch_description():
    args = [DeclareLaunchArgument(name, default_value=default, description=text)
            for name, (default, text) in ARGUMENTS.items()]
    return LaunchDescription(args + [OpaqueFunction(function=_nodes)])
