"""The commissioning loop's lines (docs/compensation.md, "Proof on logs" and "Commissioning"): ``hexsim tune
--check`` (each log of the machine running a compensator beside hexsim's prediction of it, and the verdict) and
``hexsim tune --from-logs`` (what the logs taught the model, and the improved file's predictions)."""

from __future__ import annotations

import pathlib

from hexsim.measured.proof import RUN_BAND_HZ


def check_lines(rows: list[dict], machine_label: str, compensator_name: str) -> list[str]:
    """The ``--check`` table and verdicts: ``rows`` as :func:`hexsim.measured.proof.proof` returns them (each log's
    measured and predicted smoothness, its accelerometer noise and verdict), ``machine_label`` and
    ``compensator_name`` of the prediction."""
    lines = [f"{'log':<28} {'':<10} {'mean rev. peak':>14} {'max rev. peak':>13} {'noise ratio':>11}"]
    for r in rows:
        for what in ("measured", "predicted"):
            f = r[what]
            peak = f"{f['max_reversal_peak']:.4f}" if f["max_reversal_peak"] is not None else "—"
            lines.append(f"{pathlib.Path(r['log']).name:<28} {what:<10} {f['mean_reversal_peak']:>14.4f} {peak:>13} "
                         f"{f['noise_ratio']:>11.4f}")
    lines.append(f"predicted: {machine_label} with {compensator_name} on each log's setpoints, read with the "
                 "log's accelerometer noise (m/s², from the third period)")
    for r in rows:
        models = r.get("predicted_models", [])
        if len(models) > 1:
            lines.append(f"{pathlib.Path(r['log']).name}: predicted over the calibrated file and {len(models) - 1} "
                         f"machines drawn from its uncertainty, mean reversal peak {min(models):.4f}–"
                         f"{max(models):.4f} (the predicted row above: their means)")
    for r in rows:
        measured, predicted = r["measured"].get("band_rms", {}), r["predicted"].get("band_rms", {})
        if measured:
            parts = [f"{band} {measured[band]:.4f} / {predicted[band]:.4f}"
                     + (f" ({measured[band] / predicted[band]:.1f}×)" if predicted[band] > 0 else "")
                     for band in measured]
            lines.append(f"{pathlib.Path(r['log']).name}: departure from the fundamental, rms measured / predicted "
                         f"[m/s²]: {'; '.join(parts)}")
    for r in rows:
        lines.append(f"{pathlib.Path(r['log']).name} (accelerometer noise {r['accelerometer_noise_mps2']:.3f} m/s²): "
                     f"{r['verdict']['sentence']}")
    return lines


def learned_lines(learned) -> list[str]:
    """What ``--from-logs`` read (``learned``: :class:`hexsim.measured.commissioning.Commissioning`): each log's
    null drift where one was taken out, how far each valve edge's curve reaches, from which logs."""
    curves = learned.curves
    lines = [f"{pathlib.Path(d.log).name}: the valve's null drifted {d.rate * 1e3:+.3f} ± {d.rate_se * 1e3:.3f} mV/s "
             f"from {d.offset * 1e3:+.1f} mV at its start ({d.rate * d.duration * 1e3:+.1f} mV over its "
             f"{d.duration:.0f} s); taken out of its commands before its flows were read"
             for d in learned.drifts if d.taken]
    lines.append(f"read the valve's curves from {len(learned.logs)} log(s) (P→A to {curves.pa.reach:.3g} V, A→T to "
                 f"{curves.at.reach:.3g} V): " + ", ".join(pathlib.Path(p).name for p in learned.logs))
    form = learned.form_summary()
    if form is not None:
        refitted = ", ".join(f"{key} {value:.4g}" for key, value in form["refitted"].items())
        ratio = form["held_out_flow_rms_m3"] / form["curves_held_out_flow_rms_m3"]
        verb = "kept" if form["kept"] else "replaced"
        lines.append(f"{verb} the {form['flow_area']} flow area, refitted to the same flows ({refitted}): it "
                     f"predicts their held-out windows at {ratio:.3f} of the curves' error "
                     f"({'within' if form['kept'] else 'beyond'} their standard error)")
    return lines


def predicted_lines(predicted: dict) -> list[str]:
    """The improved tuned file's predictions (its document's ``predicted``: label -> rows per motion)."""
    return [f"predicted {label:<30} {row['motion']:<9} mean rev. peak {row['final_mean_reversal_peak']:.4f}"
            for label, rows in predicted.items() for row in rows]


def step_lines(step, tuned: str) -> list[str]:
    """How the tuned file ran on the machine and what the improved file holds (``step``:
    :class:`hexsim.measured.commissioning.CommissioningStep`; ``tuned``: the file the runs ran)."""
    name = pathlib.Path(tuned).name
    lines = [f"{pathlib.Path(r.log).name}: {name} on the machine, {r.periods} periods of {r.frequency_hz:.3g} Hz, "
             f"{1e3 * r.amplitude_m:.3g} mm averaged: reversal peak {r.reversal_peak:.4f} ± {r.noise:.4f} m/s² "
             f"(below {RUN_BAND_HZ:g} Hz), seat peak {r.seat_ratio:.2f}× the perception threshold" for r in step.runs]
    lines += [f"{pathlib.Path(log).name}: not judged as a run ({why})" for log, why in step.unjudged]
    if step.kept is None:
        lines.append(f"the improved file holds the leg model learned from the logs (its compensator and settings "
                     f"{name}'s)")
    else:
        lines.append(f"the improved file keeps {pathlib.Path(step.kept['file']).name}'s compensator and leg model: "
                     f"{step.kept['because']}; the machine file with what the logs taught is --machine-out's")
    return lines
