"""Sim-to-real gap diagnosis (DESIGN section 6): where the gap lies, which effect, how far it shrinks.

``diagnose(MonitoringData) -> Diagnosis`` is the entry point; ``write_report`` (in
``bridge_shadow.gap.report``, imports matplotlib) writes the Markdown report. No ROS import, and
nothing here reads a truth twin's ground-truth file.

Modules: ``windows`` (60 s window statistics), ``drivers`` (time, temperature, lag, sun,
clearness, traffic events), ``candidates`` (the effect library: spatial signature x driver, with
plausible ranges; model-form effects act on the whole response), ``spring`` (the support spring:
exact closed form, bounded nonlinear fit), ``fit`` (bounded least squares, whole-day
cross-validation, AR(1) noise, chance level), ``where`` (the breakdown of the residual),
``posterior`` (the shadow's settlements before/after adding the named effects, from the same
``Shadow`` pipeline as ``replay``), ``levels`` (a day of records: the level changes across its
gaps, the response to known imposed steps explained with the calibration's machinery),
``diagnose``.
"""

from bridge_shadow.gap.candidates import CANDIDATES, Candidate
from bridge_shadow.gap.diagnose import Diagnosis, diagnose
from bridge_shadow.gap.errors import GapError

__all__ = ["CANDIDATES", "Candidate", "Diagnosis", "GapError", "diagnose"]
