"""Terminal output: live progress during a run, summaries after it."""
