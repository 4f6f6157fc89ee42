"""ros2 launch ambiegen_ros nav2_campaign.launch.py [nav2:=ours|bringup|external] [params_file:=<your params>]

Nav2 as the system under test: a recorder, `robot_world` (each scenario's map as a world, with
/clock at `time_scale`), Nav2, `sut_adapter` in Nav2 mode (the navigate_to_pose action, costmaps
cleared per map, Nav2's own result as the verdict) and the generator. It ends by itself like
campaign.launch.py; the log is a robot bag (/scan, /odom, /tf, /cmd_vel, /plan beside every
scenario and result).

Which Nav2 (`nav2`):
  ours      the minimum Nav2 started here: controller, planner, behaviour server, BT navigator and
            a lifecycle manager (default; with config/nav2/pioneer_navfn_dwb.yaml: NavFn + DWB)
  bringup   nav2_bringup's own navigation_launch.py, included with the merged params (Jazzy's
            full set: smoother, velocity smoother, collision monitor, waypoint follower, docking)
  external  only our side; you start Nav2 yourself in the same ROS domain, e.g.
            `ros2 launch nav2_bringup navigation_launch.py use_sim_time:=true params_file:=<merged>`
            with the file `ambiegen nav2-params` writes (the launch also writes one next to the log
            and prints the command); the adapter waits 600 s for it

The params file (yours, or the package's) gets `params_overlay` merged on (for a file of yours:
config/nav2/ambiegen_overlay.yaml, the frames, footprint, laser and base limits of our world) and
Nav2's loop rates multiplied by `time_scale` (Jazzy's loops run on wall-clock rates); it is written
next to the log. Verdicts: Nav2's own (goal succeeded = PASS, aborted = nav2_aborted, a collision,
or the time limit max(300 s, 2 x the clearance route / the controller's top speed + 60 s));
`early_verdicts:=true` lets the paper's stall and loitering monitors decide instead. Either way
each result records the early verdict beside Nav2's.

Several stacks (`nav2:=ours`): `stacks:=K` runs K stacks here, stack i in the namespace /stack<i>.
Across hosts of one ROS domain, one host runs `part:=generator stacks:=K` (the recorder and the
generator, waiting for K stacks) and each stack host `part:=stack<i>` (stack i alone, serving
campaigns until Ctrl-C).

Arguments: those of campaign.launch.py except problem/workers/keep_workers, plus nav2,
params_file, params_overlay, time_scale, map_upsample (1 m map cells to Nav2 as k x k cells),
early_verdicts, result_timeout, known_failures, stacks, part and robot_profile (the robot the world
drives and each adapter judges: docs/robot_profiles.md). The plan lives in ambiegen_ros/launch_logic.py
(plan_nav2_campaign). See docs/external_sut.md for the two-command recipe and the measured
time-scale limits.
"""
import importlib.util
from pathlib import Path

from ambiegen_ros.launch_logic import NAV2_LAUNCH_ARGUMENTS, plan_nav2_campaign

_spec = importlib.util.spec_from_file_location("ambiegen_campaign_launch", Path(__file__).with_name("campaign.launch.py"))
_campaign = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_campaign)


def generate_launch_description():
    return _campaign.campaign_launch(NAV2_LAUNCH_ARGUMENTS, plan_nav2_campaign)
