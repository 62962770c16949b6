"""``python -m solid.ros2 run|play ...``: the same as ``solid ros2 ...``."""

from . import main

raise SystemExit(main())
