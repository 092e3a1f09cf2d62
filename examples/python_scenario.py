"""A scenario built in Python, no YAML file: a slow sideways CoM sway with a push, run with tsid-torque.

    .venv/bin/python examples/python_scenario.py [OUT_DIR]
"""

import sys

from wbcbench import load_robot, make_scenario, run
from wbcbench.sim.push import Push

robot = load_robot("talos")
scenario = make_scenario(
    "sway", robot, name="slow-sway-and-push", duration=4.0,
    params={"amplitude": [0.0, 0.03, 0.0], "frequency": 0.25},     # the kind's params, validated as in YAML
    pushes=(Push(body="base", force=(60.0, 0.0, 0.0), start=2.0, duration=0.1),))
result = run(scenario, "tsid-torque", robot=robot, out=sys.argv[1] if len(sys.argv) > 1 else None)
s = result.summary
print(f"{s['scenario']}: fell={s['fell']}, CoM rms error {s['metrics']['com_rms_error_m'] * 1e3:.1f} mm, "
      f"run directory {result.run_dir}")
sys.exit(1 if s["fell"] else 0)
