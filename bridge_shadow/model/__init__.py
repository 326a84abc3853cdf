"""The bridge model: ``config/bridge.yaml`` -> FE model -> surrogate (A, u0, thermal).

Modules (no ROS import):

- ``config``: read ``bridge.yaml``, apply ``--set name=value`` overrides, sha256 of the file;
- ``mesh``: geometry and mesh as numpy arrays (girders, stiffeners, segmented slab, connectors,
  bolted joints, braces, bearings);
- ``build``: mesh -> :class:`bridge_shadow.fe.Model`, settlement / dead-load / thermal load cases;
- ``solution``: one FE solve of the surrogate load cases (unit settlements, dead load, thermal);
- ``surrogate``: A (checked against the Schur complement), u0, thermal, sensitivities, provenance;
- ``surrogate_file``: the surrogate file format (load, save, closed-form placeholder);
- ``plot``: a PNG view of the model.
"""
