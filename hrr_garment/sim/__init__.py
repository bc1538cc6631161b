"""Ground truth: the cloth simulator, presets, motion sources and the resumable dataset builder."""
