"""``python -m agnav_host.cli``: the ``agnav`` command."""

from agnav_host.cli import main

raise SystemExit(main())
