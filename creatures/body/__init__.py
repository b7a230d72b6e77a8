"""The visible body: offscreen rendering of body poses and note objects (pyrender)."""
