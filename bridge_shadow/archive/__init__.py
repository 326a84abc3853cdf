"""Archives and fleets on Dask: many bags of many bridges, the same answer as one serial replay.

The per-bag work (decode, gate, 60 s windows) runs in parallel (``reduce``); the sequential part
of the shadow then runs over the windows of each bridge in time order (``join``).
"""
