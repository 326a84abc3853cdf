"""Element formulations, each vectorized over all elements of a set."""
