"""ros2 launch ambiegen_ros campaign.launch.py problem:=robot algorithm:=nsga2 workers:=2

Starts a recorder, `workers` sim nodes of the problem and the generator (the same node set as
`ambiegen campaign` on machines without ROS). The launch ends with the campaign: when the
generator exits, every node gets SIGINT (the recorder closes the MCAP) and the campaign summary
is printed (`keep_workers:=true` stops only the recorder and leaves the sim nodes running for
external stacks until Ctrl-C). The log is `<output_dir>/<run id>_<UTC time>.mcap`; an existing
`output` file is never overwritten unless `overwrite:=true`.

Arguments: problem, algorithm, evaluations (0 = the paper's budget), time_budget (s, 0 = none),
seed (-1 = drawn), mode (surrogate | in_the_loop), workers, output_dir, output, overwrite,
keep_workers, config_file ('' = config/<problem>.yaml), profile (fidelity profile of the generator
and every sim node: replication | refined; '' = the config file's, else replication). The node
set, names and end-of-run rules live in ambiegen_ros/launch_logic.py (tested without ROS).
"""
import os
import signal
import time

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, EmitEvent, IncludeLaunchDescription, LogInfo, OpaqueFunction,
                            RegisterEventHandler)
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown, matches_action
from launch.events.process import SignalProcess
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from ambiegen_ros.launch_logic import LAUNCH_ARGUMENTS, plan_campaign, plan_summary, summary_table


def campaign_launch(arguments, plan_fn):
    """The launch description of a campaign planned by ``plan_fn(values, share_dir)`` from
    ``arguments`` (name -> (default, help)); ``nav2_campaign.launch.py`` reuses it."""

    def campaign(context):
        values = {name: LaunchConfiguration(name).perform(context) for name in arguments}
        return _actions(plan_fn(values, get_package_share_directory("ambiegen_ros")))

    args = [DeclareLaunchArgument(name, default_value=default, description=text)
            for name, (default, text) in arguments.items()]
    return LaunchDescription(args + [OpaqueFunction(function=campaign)])


def _actions(plan):
    started = time.monotonic()
    exit_codes = {}
    nodes = {f"{spec.namespace}/{spec.name}".lstrip("/"): Node(
        package=spec.package, executable=spec.executable, name=spec.name, namespace=spec.namespace or None,
        output="screen", parameters=[*spec.params_files, spec.parameters], remappings=spec.remappings)
        for spec in plan.nodes}
    recorder, generator = nodes.get("recorder"), nodes.get("generator")  # none on a host of stacks only

    def on_generator_exit(event, _context):
        exit_codes["generator"] = event.returncode
        if plan.after_generator_exit() == "shutdown":
            return [EmitEvent(event=Shutdown(reason=f"campaign {plan.run_id} done (generator exit {event.returncode})"))]
        return [LogInfo(msg=f"campaign {plan.run_id} done; stopping the recorder, keeping the sim nodes (keep_workers)"),
                EmitEvent(event=SignalProcess(signal_number=signal.SIGINT, process_matcher=matches_action(recorder)))]

    def on_recorder_exit(event, _context):
        exit_codes["recorder"] = event.returncode
        print(summary_table(plan_summary(plan, time.monotonic() - started, dict(exit_codes))), flush=True)
        if plan.after_recorder_exit(generator_done="generator" in exit_codes):
            return [EmitEvent(event=Shutdown(reason=f"recorder exited ({event.returncode})"))]
        return []

    includes = [IncludeLaunchDescription(
        PythonLaunchDescriptionSource(os.path.join(get_package_share_directory(spec.package), spec.launch_file)),
        launch_arguments=list(spec.arguments.items())) for spec in plan.includes]
    ends = [RegisterEventHandler(OnProcessExit(target_action=node, on_exit=handler))
            for node, handler in ((generator, on_generator_exit), (recorder, on_recorder_exit)) if node is not None]
    return [
        *([LogInfo(msg=f"campaign {plan.run_id}: recording to {plan.mcap}")] if recorder is not None else []),
        *[LogInfo(msg=note) for note in plan.notes],
        *ends,
        *nodes.values(),
        *includes,
    ]


def generate_launch_description():
    return campaign_launch(LAUNCH_ARGUMENTS, plan_campaign)
