"""The shadow's state: as nested plain data (``persistence``) and as a checkpoint file (``checkpoint``)."""
