"""The discrepancy workflow: find where model and measurement disagree, name the missing physical
effect, add it, refit, show the gap shrink -- and say "unexplained" rather than guess.

A pipeline of concepts, one module each (docs/explanation/discrepancy-workflow.md explains the
statistics): `options` (the workflow's levels and sizes), `effects` (the effect library, one
declaration per effect), `detectors` (is a residual noise?), `screen` (score tests and probes of
every candidate), `refit`, `selection` (accept, rival, stationarity, drop), `verdict`, `result`
(`DiagnosisResult`) and `workflow` (the `diagnose` driver). A bench log (spec §10) takes the same
statistics with the pump-level library: `pump_effects`, `pump_workflow` (`diagnose_bench`),
`pump_result` (`BenchDiagnosis`)."""
from .effects import EFFECTS, Candidate, Effect, candidates, clearance, plausible
from .pump_result import BenchDiagnosis
from .pump_workflow import diagnose_bench
from .result import DiagnosisResult
from .workflow import diagnose, tty_progress

Diagnosis = DiagnosisResult  # the API reference's name for it

__all__ = ["EFFECTS", "BenchDiagnosis", "diagnose_bench", "Candidate", "Diagnosis", "DiagnosisResult", "Effect", "candidates", "clearance", "diagnose", "plausible",
           "tty_progress"]
