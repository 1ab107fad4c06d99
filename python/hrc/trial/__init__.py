"""One trial's launcher (`hrc run`, and every study that runs trials): its options and command
lines (options), its processes and how they are stopped (processes), the run itself (run), the
experimenter's console of a live trial (console) and Python services forked from a warm parent
(prefork)."""

from hrc.trial.options import TrialOptions, TrialResult, VrOptions, default_trial_dir
from hrc.trial.processes import Terminated, stop_on_signals
from hrc.trial.run import run_trial

__all__ = [
    "Terminated",
    "TrialOptions",
    "TrialResult",
    "VrOptions",
    "default_trial_dir",
    "run_trial",
    "stop_on_signals",
]
