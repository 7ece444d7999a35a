"""The paper's model-based value-function learner and its successors (numpy/numba, no I/O)."""
