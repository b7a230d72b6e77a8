"""Percept models (thesis: "phase three – models")."""
