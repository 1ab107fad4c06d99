import sys
from pathlib import Path

# synthetic.py and offline.py, the logger's test doubles, sit next to the tests (pytest runs
# with --import-mode=importlib, which puts no test folder on sys.path).
sys.path.insert(0, str(Path(__file__).resolve().parent))
