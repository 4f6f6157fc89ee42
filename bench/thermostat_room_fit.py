"""The thermostat's physical room (issue 46): refit it to the paper's curves and draw the fit.

Usage: python bench/thermostat_room_fit.py [--picture docs/images/thermostat_room_fit.png]

Refits ``problems.thermostat_room`` (two thermal masses, the room and heater shared by the seven
models, ambient and losses per model) by least squares from a generic start, prints the
parameters beside the committed ones, and each model's error against the paper's ON and OFF
curves over 4 h. Also measures the flaw it replaces: on the old curve room, a controller that
toggles the heater every 10 s cooled a room faster than one that stays off.
Writes bench/results/thermostat_room_fit.json and the picture.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench._common import write_result  # noqa: E402


def old_room_cools_by_heating(model, minutes: float = 120.0, dt: float = 10.0) -> tuple[float, float]:
    """Temperature drop after ``minutes`` from 25 degC on the old curve room: heater off throughout,
    against on for 10 s in every minute (each switch re-anchored the cooling curve)."""
    k_on1, k_on2, k_off1, k_off2 = model
    out = []
    for toggle in (False, True):
        T, anchor, on = 25.0, 25.0, False
        for k in range(int(minutes * 60 / dt)):
            want = toggle and k % 6 == 0
            if want != on:
                on, anchor = want, T
            level, rate = (anchor + k_on1, k_on2 / 180.0) if on else (anchor - k_off1, k_off2 / 180.0)
            T = level + (T - level) * math.exp(-rate * dt)
        out.append(25.0 - T)
    return out[0], out[1]


def draw(picture: Path, construction, conditions, models) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ambiegen_ros.problems import thermostat_room as physics

    fig, axes = plt.subplots(2, 4, figsize=(13, 6), sharex=True, layout="constrained")
    minutes = np.arange(0, physics.FIT_WINDOW_MIN + 1)
    for m, ax in enumerate(axes.ravel()[:7]):
        on, off = physics.responses(construction, conditions[m], physics.operating_duty(construction, conditions[m]))
        p_on, p_off = physics.paper_curves(models[m])
        err = physics.curve_error(construction, [conditions[m]], [models[m]])[0]
        ax.plot(minutes, p_on, color="tab:red", lw=2, alpha=0.5, label="paper: heater ON")
        ax.plot(minutes, on, "--", color="tab:red", lw=1.2, label="room: heater ON")
        ax.plot(minutes, p_off, color="tab:blue", lw=2, alpha=0.5, label="paper: heater OFF")
        ax.plot(minutes, off, "--", color="tab:blue", lw=1.2, label="room: heater OFF")
        ax.set_title(f"model {m + 1}: ambient {conditions[m][0]:.1f} degC, RMSE {err['rmse']:.2f} degC", fontsize=9)
        ax.grid(True, alpha=0.3)
        if m % 4 == 0:
            ax.set_ylabel("change from the switch [degC]")
        if m >= 3:
            ax.set_xlabel("minutes after the switch")
    axes.ravel()[-1].set_axis_off()
    axes.ravel()[0].legend(fontsize=7, loc="center right")
    fig.suptitle(f"The physical room against the paper's fitted curves (both from the steady state at "
                 f"{physics.OPERATING_POINT:g} degC)", fontsize=11)
    picture.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(picture, dpi=100)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--picture", default="docs/images/thermostat_room_fit.png")
    args = ap.parse_args(argv)
    from ambiegen_ros.problems import thermostat_room as physics
    from ambiegen_ros.problems.thermostat_model import ROOM_MODELS

    t0 = time.perf_counter()
    construction, conditions, cost = physics.fit(ROOM_MODELS)
    fit_s = time.perf_counter() - t0
    committed = physics.curve_error(physics.ROOM_CONSTRUCTION, physics.ROOM_CONDITIONS, ROOM_MODELS)
    refit = physics.curve_error(construction, conditions, ROOM_MODELS)
    print(f"refit in {fit_s:.1f} s, cost {cost:.3f}")
    print(f"construction  refit {tuple(round(v, 2) for v in construction)}  committed {physics.ROOM_CONSTRUCTION}")
    rows = []
    for m in range(len(ROOM_MODELS)):
        drop_off, drop_toggle = old_room_cools_by_heating(ROOM_MODELS[m])
        rows.append({"model": m + 1, "committed": physics.ROOM_CONDITIONS[m],
                     "refit": tuple(round(v, 2) for v in conditions[m]),
                     "rmse_degC": round(committed[m]["rmse"], 3), "max_degC": round(committed[m]["max"], 3),
                     "rmse_on_degC": round(committed[m]["rmse_on"], 3), "rmse_off_degC": round(committed[m]["rmse_off"], 3),
                     "refit_rmse_degC": round(refit[m]["rmse"], 3), "duty_at_operating_point": round(committed[m]["duty"], 3),
                     "old_room_drop_in_2h_heater_off_degC": round(drop_off, 2),
                     "old_room_drop_in_2h_toggling_degC": round(drop_toggle, 2)})
        print(f"model {m + 1}: {rows[-1]}")
    draw(Path(args.picture), physics.ROOM_CONSTRUCTION, physics.ROOM_CONDITIONS, ROOM_MODELS)
    path = write_result("thermostat_room_fit", {"fit_seconds": round(fit_s, 2), "cost": cost,
                                                "construction_refit": construction,
                                                "construction_committed": physics.ROOM_CONSTRUCTION, "models": rows})
    print(f"wrote {path} and {args.picture}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
