"""The shadow's parameters.

``config`` reads and checks ``config/shadow.yaml`` (``ShadowConfig``); ``specs`` is the one table of
their types, units, ranges and descriptions.
"""
