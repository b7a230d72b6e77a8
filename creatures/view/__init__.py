"""Seeing a colony: the live view in a browser, its replay from an events log, and re-rendering
a finished run's bodies (docs/view.md)."""
