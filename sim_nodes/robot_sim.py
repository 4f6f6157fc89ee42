"""`ros2 run ambiegen_ros robot_sim`: executes robot scenarios and publishes their results."""
import sys

from sim_nodes.worker import run_worker


def main(argv=None) -> int:
    return run_worker("robot", argv)


if __name__ == "__main__":
    sys.exit(main())
