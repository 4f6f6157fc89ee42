"""`ros2 run ambiegen_ros thermostat_sim`: executes thermostat scenarios and publishes their results."""
import sys

from sim_nodes.worker import run_worker


def main(argv=None) -> int:
    return run_worker("thermostat", argv)


if __name__ == "__main__":
    sys.exit(main())
