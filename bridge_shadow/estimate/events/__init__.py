"""Events: the GLR change detector that tells a settlement step from a passing load or an outlier."""
