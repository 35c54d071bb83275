"""The scene registry is loaded by every dry run and every job: it must stay light."""

import subprocess
import sys

HEAVY = ("scipy", "pandas", "torch", "matplotlib", "h5py")


def test_loading_every_scene_imports_no_heavy_library():
    probe = ("import sys\nfrom generators import scenes\nnames = scenes.names()\n"
             f"print(len(names), *sorted(m for m in {HEAVY!r} if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.split()
    assert int(out[0]) >= 4                 # slide, meteorite, shear, collapse at least were loaded
    assert out[1:] == []                    # each of these costs 0.3-3 s to import; a scene imports it where used
