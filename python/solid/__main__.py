"""`python -m solid` is the `solid` command."""

from solid.cli import main

raise SystemExit(main())
