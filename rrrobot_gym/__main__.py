"""``python -m rrrobot_gym``: the same command line as the ``rrrobot`` script."""

from .cli import main

raise SystemExit(main())
