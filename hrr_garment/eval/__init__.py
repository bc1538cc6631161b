"""Evaluation: metrics against simulated ground truth, mode comparisons, reports (hrr-eval)."""
