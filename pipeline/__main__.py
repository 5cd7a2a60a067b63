"""``python -m pipeline`` is the same as the ``dualtrack`` command."""

from pipeline.cli import main

raise SystemExit(main())
