"""``python -m ambiegen_ros.doctor``: the checks where ``ambiegen`` itself cannot start."""
import sys

from . import main

sys.exit(main())
