"""What the sweep benches share: the bundled cities, a sweep run through
`raysweep run CITY --until sweep` with its summary parsed, and a dataset's
sensitivity floor. Imported by spike_bench.py and lattice_bench.py; not a
bench of its own."""
import json
import os
import re
import subprocess
import time

import h5py

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
RING = os.path.join(ROOT, "datasets", "van3twin-ring", "city.toml")
DEMO = os.path.join(ROOT, "datasets", "demo", "city.toml")
RING_SUMO = os.path.join(os.path.dirname(ROOT), "shared", "data", "van3twin", "DriveX-devs_VaN3Twin", "src",
                         "automotive", "examples", "sumo_files_v2v_map")


def sweep(rs, city, out, sets):
    """Runs the city up to its sweep; the sweep's wall and tracing seconds."""
    stamp = os.path.join(out, ".stamps", "sweep.json")  # the sweep runs again every time, the stages before it not
    if os.path.exists(stamp):
        os.remove(stamp)
    cmd = [rs, "run", city, "--out", out, "--until", "sweep"]
    for s in sets:
        cmd += ["--set", s]
    print("+", " ".join(cmd), flush=True)
    t0 = time.monotonic()
    p = subprocess.run(cmd, check=True, capture_output=True, text=True)
    log = p.stdout + p.stderr
    m = re.search(r"swept (\d+) frames .*?, (\d+) pair-channels \((\d+) traced, cache hit.*? in "
                  r"([0-9.]+) s \(([0-9.]+) s tracing[;)]", log)
    if not m:
        raise SystemExit(f"no sweep summary in the log of {' '.join(cmd)}:\n{log[-2000:]}")
    return {"frames": int(m.group(1)), "traced": int(m.group(3)), "sweep_s": float(m.group(4)),
            "trace_s": float(m.group(5)), "process_s": time.monotonic() - t0}


def floor_of(path):
    """sensitivity - tx power of the [radio] the dataset was swept with."""
    with h5py.File(path, "r") as f:
        radio = json.loads(f.attrs["config"])["radio"]
    return radio["sensitivity_dbm"] - radio["tx_power_dbm"]
