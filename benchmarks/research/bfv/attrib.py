"""Step 1: streaming identifier, B_fv error split into bias/spread, per noise channel."""
from common import *
true = PlantParams().identified()
for spec in ["none", "realistic", "only:x3+x4", "only:x1", "only:x5", "only:x1+x5", "stress",
             "stressonly:x3+x4", "stressonly:x1"]:
    n = 1 if spec == "none" else 10
    runs = runs_for(spec, seeds=n)
    st = streaming(runs)
    print(f"{spec:18s} B_fv  {fmt(summary(*st['B_fv'], true['B_fv']))}")
    for nm in ("m", "K_t", "f_c"):
        print(f"{'':18s} {nm:5s} {fmt(summary(*st[nm], true[nm]))}")
