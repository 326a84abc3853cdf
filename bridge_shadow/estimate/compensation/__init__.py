"""Temperature compensation.

The temperature curve fitted jointly with the segment levels (``fit``, on the smoothing spline of
``spline`` and the sufficient statistics of ``sums``), and the noise model from its residuals
(``noise``).
"""
