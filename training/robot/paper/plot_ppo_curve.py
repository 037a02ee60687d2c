"""Learning curve of the shipped paper-scene policy's PPO stages -> docs/img/robot_paper_ppo_curve.png.

Stage 3 (13_ppo_from_graded_dagger1) and stage 4 (14_ppo_stage2, a new run from stage 3's snapshot whose
step count restarted at 0) on one axis of robot steps since the DAgger-1 start. Dotted lines: the stage
boundary and the shipped export. Run from the repository root: python training/robot/paper/plot_ppo_curve.py
"""

import json
import tempfile
from pathlib import Path

from navzoo.agents.robot_train import plot_learning_curve

HERE = Path(__file__).resolve().parent
STAGE3_END, SHIPPED = 117_264, 116_016  # stage 3's last step; stage 4's step of the shipped export

rows = [json.loads(s) for s in (HERE / "13_ppo_from_graded_dagger1" / "metrics.jsonl").read_text().splitlines() if s]
for s in (HERE / "14_ppo_stage2" / "metrics.jsonl").read_text().splitlines():
    if s:
        r = json.loads(s)
        rows.append({**r, "timesteps": r["timesteps"] + STAGE3_END})
with tempfile.TemporaryDirectory() as tmp:
    joined = Path(tmp) / "metrics.jsonl"
    joined.write_text("".join(json.dumps(r) + "\n" for r in rows))
    out = plot_learning_curve(joined, HERE.parents[2] / "docs" / "img" / "robot_paper_ppo_curve.png",
                              title="transformer-ppo, paper scenes: PPO from DAgger-1 (stage 3 | stage 4; shipped at the second line)",
                              marks=(STAGE3_END, STAGE3_END + SHIPPED))
print(out)
