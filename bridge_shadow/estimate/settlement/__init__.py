"""The settlement filter.

The posterior over segments of constant settlement (``segments``), the paper's prior (``prior``),
its Kalman filter (``kalman``) and its batch method on a whole record (``batch``).
"""
