"""ros2 launch ambiegen_ros nav2_campaign.launch.py params_file:=<your nav2 params.yaml> evaluations:=200

Nav2 as the system under test: a recorder, `robot_world` (each scenario's map as a world, with
/clock at `time_scale`), Nav2 (controller, planner, behaviour server, BT navigator and a
lifecycle manager, all on the world's clock, with your params file or the package's
config/nav2/pioneer_navfn_dwb.yaml for a pioneer-sized robot with NavFn + DWB), `sut_adapter` in
Nav2 mode (the navigate_to_pose action, costmaps cleared per map, Nav2's result recorded) and the
generator. It ends by itself like campaign.launch.py; the log is a robot bag (/scan, /odom, /tf,
/cmd_vel, /plan beside every scenario and result).

Arguments: those of campaign.launch.py except problem/workers/keep_workers, plus params_file,
time_scale (Nav2's loop rates are multiplied by it in a copy of the params file written next to
the log: Jazzy's loops run on wall-clock rates), map_upsample (1 m map cells to Nav2 as k x k
cells) and result_timeout. The plan lives in ambiegen_ros/launch_logic.py (plan_nav2_campaign).
See docs/external_sut.md for the measured time-scale limits.
"""
import importlib.util
from pathlib import Path

from ambiegen_ros.launch_logic import NAV2_LAUNCH_ARGUMENTS, plan_nav2_campaign

_spec = importlib.util.spec_from_file_location("ambiegen_campaign_launch", Path(__file__).with_name("campaign.launch.py"))
_campaign = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_campaign)


def generate_launch_description():
    return _campaign.campaign_launch(NAV2_LAUNCH_ARGUMENTS, plan_nav2_campaign)
