"""The colony the input-map tests feed: ``bo`` hears outside input, ``deaf`` (``hears_input =
false``) only other creatures; both are exchange creatures, with drives and an action-group."""

COLONY = """
title = "input map"
tick = 0.02
[[creature]]
name = "bo"
kind = "exchange"
[[creature]]
name = "deaf"
kind = "exchange"
channel = 1
hears_input = false
"""
