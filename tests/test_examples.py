"""Every numbered example runs in its fast mode and leaves a non-empty picture.

Each ``examples/NN_*.py`` runs in a subprocess with ``RATECTL_FAST=1`` and
``MPLBACKEND=Agg``; it must exit 0, print a summary, and write a picture
``examples/out/NN_*.png`` (or ``.gif``) during the run that is larger than 5 kB and
not a single colour.
"""

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
SCRIPTS = sorted(p for p in EXAMPLES.glob("[0-9][0-9]_*.py"))
#: What an example's summary must say (the documentation describes these outcomes).
EXPECT = {
    "07": ["follow (governor) of UR5e: completed", "max |p_sim − p_kin|"],
    "08": ["without collision rows: min distance -", "COLLISION of link",
           "with collision rows:    min distance +"],
}


def test_the_numbered_examples_exist():
    numbers = {p.name[:2] for p in SCRIPTS}
    assert {"01", "02", "03", "04", "05", "06"} <= numbers


def _pixels(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        frames = []
        for k in range(getattr(im, "n_frames", 1)):
            im.seek(k)
            frames.append(np.asarray(im.convert("RGB"), dtype=float))
    return np.stack(frames)


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.stem for p in SCRIPTS])
def test_example_runs_and_draws(script):
    env = dict(os.environ, RATECTL_FAST="1", MPLBACKEND="Agg")
    env.setdefault("MUJOCO_GL", "egl")
    start = time.time()
    proc = subprocess.run([sys.executable, str(script)], cwd=EXAMPLES.parent, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"{script.name} failed:\n{proc.stdout[-2000:]}\n{proc.stderr[-4000:]}"
    assert proc.stdout.strip(), f"{script.name} printed no summary"
    for words in EXPECT.get(script.name[:2], []):
        assert words in proc.stdout, f"{script.name}: {words!r} not in its summary:\n{proc.stdout}"
    prefix = script.name[:3]                      # "NN_"
    pictures = [p for p in (EXAMPLES / "out").glob(prefix + "*")
                if p.suffix.lower() in (".png", ".gif") and p.stat().st_mtime >= start - 1]
    assert pictures, f"{script.name} wrote no picture under examples/out/ during the run"
    for pic in pictures:
        assert pic.stat().st_size > 5_000, f"{pic.name} is only {pic.stat().st_size} bytes"
        px = _pixels(pic)
        assert float(px.reshape(-1, 3).std(axis=0).max()) > 1.0, f"{pic.name} is a single colour"
