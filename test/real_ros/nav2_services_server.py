"""What Nav2 answers besides topics, served by rclpy (nav2_msgs, lifecycle_msgs), for the DDS client.

Run under the ROS python: ``python3 nav2_services_server.py``. It serves, from one node:

* ``navigate_to_pose`` (nav2_msgs/action/NavigateToPose), by the goal's ``pose.position.x``:
  ``x < 0`` rejected; ``1``: one feedback with 2 recoveries, then succeeded; ``2``: one feedback
  with 1 recovery, then aborted with error 102 and a message; ``3``: feedback every 10 ms (Nav2's
  100 Hz) until cancelled, then canceled;
* ``/controller_server/get_state`` (lifecycle_msgs/srv/GetState): ``active`` (id 3);
* ``/planner_server/get_state``: ``inactive`` (id 2), so a client keeps asking;
* ``/global_costmap/clear_entirely_global_costmap`` (nav2_msgs/srv/ClearEntireCostmap): counts and
  prints each call (``cleared N``).

Prints ``ready`` once everything is up and ``goal <x> <frame>`` for each goal it receives.
"""
import sys
import threading
import time

import rclpy
from lifecycle_msgs.msg import State
from lifecycle_msgs.srv import GetState
from nav2_msgs.action import NavigateToPose
from nav2_msgs.srv import ClearEntireCostmap
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor


def main() -> int:
    rclpy.init()
    node = rclpy.create_node("bt_navigator")
    group = ReentrantCallbackGroup()
    cleared = [0]

    def goal_callback(request):
        print(f"goal {request.pose.pose.position.x:g} {request.pose.header.frame_id}", flush=True)
        return GoalResponse.REJECT if request.pose.pose.position.x < 0 else GoalResponse.ACCEPT

    def execute(goal_handle):
        x = goal_handle.request.pose.pose.position.x
        feedback = NavigateToPose.Feedback()
        feedback.current_pose = goal_handle.request.pose
        result = NavigateToPose.Result()
        if x == 3:
            while not goal_handle.is_cancel_requested:
                feedback.number_of_recoveries = 0
                goal_handle.publish_feedback(feedback)
                time.sleep(0.01)
            goal_handle.canceled()
            print("canceled", flush=True)
            return result
        feedback.number_of_recoveries = 2 if x == 1 else 1
        goal_handle.publish_feedback(feedback)
        time.sleep(0.2)
        if x == 2:
            result.error_code, result.error_msg = 102, "fake: the controller failed to make progress"
            goal_handle.abort()
            return result
        goal_handle.succeed()
        return result

    ActionServer(node, NavigateToPose, "navigate_to_pose", execute, goal_callback=goal_callback,
                 cancel_callback=lambda _goal: CancelResponse.ACCEPT, callback_group=group)

    def state(label: str, ident: int):
        def serve(_request, response):
            response.current_state = State(id=ident, label=label)
            return response
        return serve

    node.create_service(GetState, "/controller_server/get_state", state("active", 3))
    node.create_service(GetState, "/planner_server/get_state", state("inactive", 2))

    def clear(_request, response):
        cleared[0] += 1
        print(f"cleared {cleared[0]}", flush=True)
        return response

    node.create_service(ClearEntireCostmap, "/global_costmap/clear_entirely_global_costmap", clear)
    executor = MultiThreadedExecutor(num_threads=3)
    executor.add_node(node)
    threading.Timer(0.5, lambda: print("ready", flush=True)).start()
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
