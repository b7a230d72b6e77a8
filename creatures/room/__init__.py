"""Creatures in a room: a 2-D floor with walls and obstacles, vehicles that move on it, the
steering behaviours that move them (Reynolds' OpenSteer and REACT's reactive layer), what
they see and hear there, where their sound comes from, and the director's zones, paths and
flow fields.

One way through a sub-step (STYLE.md, "one way through a tick"): the spatial index
(:mod:`.index`) → steering forces (:mod:`.steering`) → one force per creature
(:mod:`.combine`) → the vehicle model (:mod:`.vehicle`) → the room's walls (:mod:`.space`).
:mod:`.motion` runs that on clock time with fixed sub-steps; :mod:`.lod` chooses which
creatures steer on a given sub-step.
"""
