"""hrc-cosim orchestrator: scenario, task logic, safety policies, cues, metrics."""
