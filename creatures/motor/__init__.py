"""The motor system: quaternions, body poses, note-space motor graphs searched with A*,
motor programs and gesture models (thesis: "graph-based motor systems")."""
