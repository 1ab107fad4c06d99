"""hrc-cosim logger: rerun live view and recording, thesis-style text log, JSONL events."""
