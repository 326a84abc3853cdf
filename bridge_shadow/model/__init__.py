"""The bridge model: ``config/bridge.yaml`` -> FE model -> surrogate (A, u0, thermal)."""
