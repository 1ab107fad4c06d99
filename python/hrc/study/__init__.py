"""Studies: a study file (factors, participants, repetitions) swept over trials, and its report.

    from hrc.study import load_study, sweep
    study = load_study("studies/thesis-speed-anticipation.toml")   # StudyError lists problems
    records = sweep(study, Path("runs/study"), workers=2)          # trials.parquet, trials.csv

The format and the outputs are documented in docs/studies.md.
"""

from hrc.study.spec import Person, Study, StudyError, Trial, load_study
from hrc.study.sweep import sweep
from hrc.study.trial import Record

__all__ = ["Person", "Record", "Study", "StudyError", "Trial", "load_study", "sweep"]
