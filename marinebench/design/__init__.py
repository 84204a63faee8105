"""Offline designs: LMI problems (cvxpy + CLARABEL) re-verified in numpy."""
