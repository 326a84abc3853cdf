"""Sim-to-real gap diagnosis (DESIGN section 6): where the gap lies, which effect, how far it shrinks.

``diagnose(MonitoringData) -> Diagnosis`` is the entry point; ``write_report`` (in
``bridge_shadow.gap.report``, imports matplotlib) writes the Markdown report. No ROS import, and
nothing here reads a truth twin's ground-truth file.

Modules: ``windows`` (60 s window statistics of a record, from ``bridge_shadow.windowing``),
``drivers`` (time, temperature, lag, sun, clearness, traffic events), ``candidates`` (the effect
library: spatial signature x driver, with plausible ranges; model-form effects act on the whole
response), ``spring`` (the support spring: exact closed form, bounded nonlinear fit), ``fit``
(bounded least squares, whole-day cross-validation, AR(1) noise, chance level), ``records`` and
``day_levels`` (a day of records and its levels), ``levels`` (the level changes across its gaps,
the response to known imposed steps explained with the calibration's machinery), ``residual``
(the residual against the baseline model, its folds), ``fitter`` (the candidates fitted to it),
``rank`` (ranking, the best effect's group, forward selection), ``explain`` (the model change the
named effects make, stand-ins, the statement), ``posterior`` (the shadow's settlements
before/after adding the named effects, from the same ``Shadow`` pipeline as ``replay``),
``where`` (the breakdown of the residual), ``summary`` (the JSON), ``report`` (Markdown and
plots), and ``diagnose``, which composes them.
"""

from bridge_shadow.gap.candidates import CANDIDATES, Candidate
from bridge_shadow.gap.diagnose import Diagnosis, diagnose
from bridge_shadow.gap.errors import GapError

__all__ = ["CANDIDATES", "Candidate", "Diagnosis", "GapError", "diagnose"]
