"""``python -m ambiegen_ros.doctor``: the checks where ``ambiegen`` itself cannot start."""
import sys

from ..cli.doctor import main

sys.exit(main())
