"""Sinks: the only code that writes run files or imports rerun / matplotlib."""
