"""Start a shadow from its checkpoint, or fresh: what the node and ``replay --checkpoint`` share.

With ``checkpoint_path`` set: the target is checked for writing now (not at the first save),
temporary files of killed writers are removed, and an existing checkpoint is resumed when it is
readable and was saved under the parameters in force. Otherwise ``checkpoint_unusable`` decides:
``stop`` raises CheckpointError (one line naming the file and why; the file is left as it is),
``fresh`` renames the file to ``<path>.unusable-<UTC time>`` and starts from the prior.
"""

from __future__ import annotations

from bridge_shadow.estimate.inputs.gate import MESSAGE_REASONS
from bridge_shadow.estimate.parameters.config import ShadowConfig
from bridge_shadow.estimate.shadow import Shadow
from bridge_shadow.estimate.state.checkpoint import CheckpointError, check_target, remove_orphans, set_aside
from bridge_shadow.model.surrogate_file import Surrogate

__all__ = ["UNUSABLE_HINT", "open_shadow"]


#: What an unusable checkpoint's error adds: the parameter that starts from the prior instead.
UNUSABLE_HINT = "checkpoint_unusable: fresh sets it aside and starts from the prior"


def open_shadow(config: ShadowConfig, surrogate: Surrogate) -> tuple[Shadow, list[str]]:
    """Return the shadow to run (resumed or fresh) and lines saying what was done.

    Raises:
        CheckpointError: the checkpoint cannot be written, or it is unusable and
            ``checkpoint_unusable`` is ``stop``.

    """
    notes: list[str] = []
    if not config.checkpoint_path:
        return Shadow(config, surrogate), notes
    file = check_target(config.checkpoint_path)
    notes += [f"removed {p.name}, left by a checkpoint writer that was killed" for p in remove_orphans(file)]
    if not file.exists():
        notes.append(f"checkpoint {file}: none yet, starting from the prior")
        return Shadow(config, surrogate), notes
    try:
        shadow = Shadow.resume(file, config, surrogate)
    except CheckpointError as err:
        if config.checkpoint_unusable != "fresh":
            raise CheckpointError(f"{err} ({UNUSABLE_HINT})") from None
        aside = set_aside(file)
        what = f"set aside as {aside.name}, starting from the prior (checkpoint_unusable: fresh)"
        notes.append(f"{err}; {what}")
        return Shadow(config, surrogate), notes
    # messages, not windows: the rejected counts hold window reasons too (traffic)
    taken = sum(shadow.used.values()) + sum(n for r, n in shadow.rejected.items() if r in MESSAGE_REASONS)
    counts = f"{taken} messages, {shadow.n_windows} windows, {shadow.filter.n_updates} updates"
    if shadow.held_air is not None:  # a replay's: the air past its bag's last force (``replay.air_tail``)
        counts += f", {len(shadow.held_air)} air readings held unfed for the next bag"
    notes.append(f"resumed from {file}: {counts}")
    return shadow, notes
