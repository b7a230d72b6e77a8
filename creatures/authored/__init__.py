"""Authored creatures: a creature declared in the config, in the thesis's vocabulary
(thesis: "motivation-based authoring"; DESIGN.md "Authored creatures").

``kind = "authored"`` names drives, percepts (and their trees), action-tuples (Tr, Ac, Du, V),
action-groups and learning settings; every name resolves at load against the registries of
:mod:`creatures.authored.registry`, which the built-in parts join exactly as a user's plugin
does (package entry points, or a ``plugins = ["my_actions.py"]`` file next to the config).
"""
