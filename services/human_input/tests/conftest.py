import sys
from pathlib import Path

# minisim.py, the participant's test world, sits next to the tests (pytest runs with
# --import-mode=importlib, which puts no test folder on sys.path).
sys.path.insert(0, str(Path(__file__).resolve().parent))
