"""The motor system (thesis "graph-based motor systems", "towards a complete motor system").

- :mod:`~creatures.motor.quaternion` — joint-angle maths (appendix "(quaternions)")
- :mod:`~creatures.motor.skeleton`, :mod:`~creatures.motor.pose` — Skeleton, BodyPose, PoseSet
- :mod:`~creatures.motor.bvh`, :mod:`~creatures.motor.animations` — source material
- :mod:`~creatures.motor.metric` — the BodyPose distance metric (figure 28)
- :mod:`~creatures.motor.graph` — MotorGraph: automatic topology, re-editing, JSON files
- :mod:`~creatures.motor.search` — A* to labels, label sets, low-energy states, end-effector goals
- :mod:`~creatures.motor.playback` — squad interpolation of paths against clock time
- :mod:`~creatures.motor.programs` — motor programs, program graphs, the stack machine
- :mod:`~creatures.motor.note_space` — notes ↔ places, "strike the nearest note", exchange metric
- :mod:`~creatures.motor.gesture` — BodyMemory and gesture models over node identities
- :mod:`~creatures.motor.adverbs` — RBF adverb blending in neutral time
"""
