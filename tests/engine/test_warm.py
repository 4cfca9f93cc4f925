"""A node's warm-up compiles every kernel its first messages use (``hydromon.engine.warm``)."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# in a fresh interpreter (this one has compiled everything already): after warm_up(), grading a
# fleet's first messages, samples and frames, must not give any numba dispatcher a new signature
# (on a cold cache each one is a compile of seconds inside the node's loop)
PROBE = textwrap.dedent("""
    import sys
    sys.path.insert(0, "tests")
    from numba.core.registry import CPUDispatcher
    from hydromon.engine.warm import warm_up
    from hydromon.engine.core import MonitorCore
    from helpers import fleet_messages
    from hydromon.store.fleetfile import default_fleet

    def dispatchers():
        out = {}
        for name, mod in list(sys.modules.items()):
            if name.split(".")[0] in ("hydromon", "monitor", "plant_sim"):
                for attr, obj in vars(mod).items():
                    if isinstance(obj, CPUDispatcher):
                        out[f"{name}.{attr}"] = len(obj.signatures)
        return out

    warm_up()
    spec = default_fleet(noise="realistic")
    messages = fleet_messages(spec, 2.0) + fleet_messages(spec, 2.0, frame=10)
    before = dispatchers()
    core = MonitorCore(eval_every=10)
    health = core.process(messages)
    core.process(messages[-1:])
    after = dispatchers()
    grew = {k: (before.get(k, 0), n) for k, n in after.items() if n > before.get(k, 0) and k.split(".")[0] != "plant_sim"}
    assert health, "no health from the fleet's messages"
    assert not grew, grew
    print("ok", len(after))
""")


def test_after_the_warm_up_a_cores_first_samples_and_frames_compile_nothing():
    done = subprocess.run([sys.executable, "-c", PROBE], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0 and done.stdout.startswith("ok"), done.stdout + done.stderr
