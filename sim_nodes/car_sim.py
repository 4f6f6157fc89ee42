"""`ros2 run ambiegen_ros car_sim`: executes vehicle scenarios and publishes their results."""
import sys

from sim_nodes.worker import run_worker


def main(argv=None) -> int:
    return run_worker("vehicle", argv)


if __name__ == "__main__":
    sys.exit(main())
