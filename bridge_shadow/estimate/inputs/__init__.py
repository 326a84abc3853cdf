"""Inputs of the shadow.

The message gate per topic (``gate``), its bookkeeping (``ledger``), the window buffer (``windows``)
and the closed window on its way to an output (``closed_window``).
"""
