import sys

from .entry import launch

sys.exit(launch("ambiegen"))
