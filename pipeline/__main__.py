"""``python -m pipeline`` is the same as the ``dualtrack`` command."""

from pipeline._entry import entry

entry()
