"""``python -m solid.ros2 run|play ...``: the same as ``solid ros2 ...``."""

from . import main

if __name__ == "__main__":  # not when the back-end's process (spawned) imports this module
    raise SystemExit(main())
