"""Draw docs/img/robot_crowdnav_curve.png: the shipped CrowdNav policy's whole lineage.

Stage 1 (metrics.jsonl, robot steps 0 -> 1,079,424) and the fine-tune that started from its export
(metrics_finetune.jsonl, whose step counts restart at 0) on one axis.
Run from the repository root: python training/robot/crowdnav/plot_curve.py
"""
import json
import tempfile
from pathlib import Path

from navzoo.agents.robot_train import plot_learning_curve

HERE = Path(__file__).parent
STAGE1_END = 1_079_424  # the export the fine-tune started from (--init-from)

rows = [json.loads(x) for x in (HERE / "metrics.jsonl").read_text().splitlines() if x.strip()]
rows = [r for r in rows if r.get("timesteps", 0) <= STAGE1_END]
for line in (HERE / "metrics_finetune.jsonl").read_text().splitlines():
    if line.strip():
        r = json.loads(line)
        if "timesteps" in r:
            rows.append({**r, "timesteps": r["timesteps"] + STAGE1_END})
with tempfile.TemporaryDirectory() as tmp:
    merged = Path(tmp) / "metrics.jsonl"
    merged.write_text("".join(json.dumps(r) + "\n" for r in rows))
    out = plot_learning_curve(merged, "docs/img/robot_crowdnav_curve.png",
                              title="transformer + PPO, CrowdNav circle crossing, diff-drive "
                                    "(lines: forward-only from 761k; fine-tune at lr 5e-5 from 1.08M)",
                              marks=(761_088, STAGE1_END))
print(out)
