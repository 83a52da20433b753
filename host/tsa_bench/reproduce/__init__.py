"""The thesis's chapter-3 modelling procedures reproduced on simulated runs (issue 7)."""
