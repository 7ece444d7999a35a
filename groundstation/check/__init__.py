"""`dive check URL`: a conformance suite that drives any agent over any link and reports per SPEC.md section."""

from groundstation.check.probe import Timeouts
from groundstation.check.registry import Check, Outcome, Result
from groundstation.check.runner import CheckOptions, Report, run_checks, selected

__all__ = ["Check", "CheckOptions", "Outcome", "Report", "Result", "Timeouts", "run_checks", "selected"]
