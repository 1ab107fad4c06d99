import sys
from pathlib import Path

# The fakes module sits next to the tests (pytest runs with --import-mode=importlib).
sys.path.insert(0, str(Path(__file__).resolve().parent))
