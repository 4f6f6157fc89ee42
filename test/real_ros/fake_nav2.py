"""A stand-in for Nav2's bt_navigator: a typed ``navigate_to_pose`` action server (rclpy, nav2_msgs).

Run under the ROS python: ``python3 fake_nav2.py GOAL_TOPIC [abort|recover|refuse-first]``. Each accepted goal is
printed (``goal x y frame``), forwarded as ``geometry_msgs/PoseStamped`` on GOAL_TOPIC (where
``external_sim`` drives the robot, as Nav2's planner + controller would), and succeeds after one
feedback message, so the adapter sees a real action round trip (with ``early_verdicts`` the
verdict still comes from odometry). With ``abort`` it aborts every goal instead, with Nav2's
error code 102 and a message, as Nav2 does when its controller gives up, its feedback counting
the 2 recovery rounds it ran first. With ``recover`` every goal succeeds, its feedback counting 1
recovery round (a near miss). With ``refuse-first``
it aborts the first goal at once, unforwarded, with 103 "Resulting plan has 0 poses in it." (as
MPPI's controller did once after a world reset), and serves every later goal normally.
"""
import sys
import time

import rclpy
from geometry_msgs.msg import PoseStamped
from nav2_msgs.action import NavigateToPose
from rclpy.action import ActionServer
from rclpy.executors import ExternalShutdownException


def main() -> int:
    rclpy.init()
    node = rclpy.create_node("bt_navigator")
    forward = node.create_publisher(PoseStamped, sys.argv[1], 10)

    goals = []

    def execute(goal_handle):
        pose = goal_handle.request.pose
        goals.append(pose)
        if sys.argv[2:3] == ["refuse-first"] and len(goals) == 1:
            print("goal refused", flush=True)
            result = NavigateToPose.Result()
            result.error_code, result.error_msg = 103, "Resulting plan has 0 poses in it."
            goal_handle.abort()
            return result
        print(f"goal {pose.pose.position.x:.6f} {pose.pose.position.y:.6f} {pose.header.frame_id}", flush=True)
        forward.publish(pose)
        feedback = NavigateToPose.Feedback()
        feedback.current_pose = pose
        feedback.number_of_recoveries = {"abort": 2, "recover": 1}.get(sys.argv[2] if len(sys.argv) > 2 else "", 0)
        goal_handle.publish_feedback(feedback)
        time.sleep(0.2)
        result = NavigateToPose.Result()
        if sys.argv[2:3] == ["abort"]:
            result.error_code, result.error_msg = 102, "fake: the controller failed to make progress"
            goal_handle.abort()
            return result
        goal_handle.succeed()
        return result

    ActionServer(node, NavigateToPose, "navigate_to_pose", execute)
    print("navigate_to_pose ready", flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
