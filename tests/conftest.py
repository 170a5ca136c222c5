"""Makes the repository importable (reactive_anim, tools, tests.support) without installing it."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
