"""Diagnosis outputs: the JSON file (schema ``cablekit.diagnosis/3``, see docs/diagnosis.md) and a
self-contained HTML report with plots (matplotlib, from the ``report`` extra)."""

from __future__ import annotations

import base64
import html
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from cablekit.diagnose.data import scored_start
from cablekit.diagnose.result import SCHEMA, Diagnosis

__all__ = ["to_json", "validate", "write_html", "write_json"]


def to_json(result: Diagnosis) -> dict[str, Any]:
    """The ``diagnosis.json`` document of a result (:meth:`Diagnosis.to_json`)."""
    return result.to_json()


def write_json(result: Diagnosis, path: str | Path) -> Path:
    path = Path(path)
    doc = to_json(result)
    validate(doc)
    path.write_text(json.dumps(doc, indent=2))
    return path


VERDICTS = ("no_significant_gap", "explained", "ambiguous", "partially_explained")


def validate(doc: dict[str, Any]) -> None:
    """Check a diagnosis document against the schema of docs/diagnosis.md; raises ValueError."""

    def need(d: dict[str, Any], keys: list[str], where: str) -> None:
        for k in keys:
            if k not in d:
                raise ValueError(f"diagnosis JSON: {where} lacks {k!r}")

    need(
        doc,
        ["schema", "verdict", "flags", "effects", "selected", "where", "gap", "skipped", "meta"],
        "document",
    )
    if doc["schema"] != SCHEMA:
        raise ValueError(f"diagnosis JSON: unknown schema {doc['schema']!r}")
    if doc["verdict"] not in VERDICTS:
        raise ValueError(f"diagnosis JSON: verdict {doc['verdict']!r} not in {VERDICTS}")
    names = set()
    for i, e in enumerate(doc["effects"]):
        need(
            e,
            [
                "name",
                "id",
                "site",
                "form",
                "sentence",
                "selected",
                "parameters",
                "fit",
                "held_out",
                "identifiability",
                "status",
            ],
            f"effects[{i}]",
        )
        need(
            e["held_out"],
            ["gap_before", "gap_after", "closed_fraction", "interval", "significant"],
            f"effects[{i}].held_out",
        )
        need(e["fit"], ["gap_before", "gap_after", "closed_fraction"], f"effects[{i}].fit")
        for p in e["parameters"]:
            need(p, ["name", "unit", "value", "ci95"], f"effects[{i}].parameters")
        names.add(e["id"])
    for s in doc["selected"]["effects"]:
        if s not in names:
            raise ValueError(f"diagnosis JSON: selected effect {s!r} is not among the ranked effects")
    need(
        doc["selected"],
        ["held_out", "fit", "channels_held_out", "per_channel", "per_condition_held_out", "unexplained_gap"],
        "selected",
    )
    for i, c in enumerate(doc["selected"]["channels_held_out"]):
        need(
            c,
            ["channel", "gap_before", "gap_after", "change", "worsened"],
            f"selected.channels_held_out[{i}]",
        )
    need(doc["where"], ["conditions_fit", "conditions_held_out", "residual_tests"], "where")


# ---- HTML ---------------------------------------------------------------------------------------


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    return base64.b64encode(buf.getvalue()).decode()


def _img(b64: str, alt: str) -> str:
    return f'<img alt="{html.escape(alt)}" src="data:image/png;base64,{b64}"/>'


def _table(rows: list[list[Any]], head: list[str]) -> str:
    h = "".join(f"<th>{html.escape(x)}</th>" for x in head)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def _fmt(v: Any, digits: int = 3) -> str:
    if v is None:
        return "–"
    if isinstance(v, float):
        return f"{v:.{digits}g}"
    return str(v)


def _centred_mean(x: np.ndarray, w: int) -> np.ndarray:
    """The core's residual averaging (``Channel.window``): a centred mean of ``w`` samples, its
    window clamped inside the series."""
    n = len(x)
    if w <= 1 or n == 0:
        return x
    w = min(w, n)
    c = np.concatenate([[0.0], np.cumsum(x)])
    lo = np.clip(np.arange(n) - w // 2, 0, n - w)
    return (c[lo + w] - c[lo]) / w


def _figures(result: Diagnosis) -> dict[str, str]:
    """Plots from the internal objects of a fresh result (not available from JSON alone)."""
    from cablekit.plotting import pyplot_or_none

    plt = pyplot_or_none()
    if plt is None:  # pragma: no cover - depends on the environment
        return {}
    inner = result.internal
    if not inner:
        return {}
    prep, current = inner["prep"], inner["current"]
    figs: dict[str, str] = {}
    run = prep.hold_runs[0]
    start = scored_start(prep.spec.warmup, run)
    t = run.t[start:]
    meas = np.column_stack([run.column(c) for c in prep.columns])[start:]
    nominal = prep.hold0.predict(np.zeros(0), 0)[start:]
    if current.effects:
        aug = prep.hold0.with_effects(current.effects, current.substeps).predict(current.params, 0)[start:]
    else:
        aug = nominal
    worst = result.where.conditions_held_out[0] if result.where.conditions_held_out else None
    masks = (
        dict(((f, n), m) for f, n, m in inner.get("hold_masks", [[]])[0]) if inner.get("hold_masks") else {}
    )
    q = prep.q
    fig, axes = plt.subplots(2 * q, 1, figsize=(10, 2.6 * 2 * q), sharex=True)
    axes = np.atleast_1d(axes)
    for c, name in enumerate(prep.channel_names):
        ax = axes[2 * c]
        ax.plot(t, meas[:, c], color="0.6", lw=0.8, label="measured (held-out)")
        ax.plot(t, nominal[:, c], color="tab:red", lw=0.9, label="nominal model")
        if current.effects:
            ax.plot(t, aug[:, c], color="tab:blue", lw=0.9, label="+ " + " + ".join(current.effects))
        ax.set_ylabel(name)
        ax.legend(loc="upper right", fontsize=7)
        ax = axes[2 * c + 1]
        w = prep.windows[c] if prep.windows else 1
        tag = f" ({w}-sample mean, as scored)" if w > 1 else ""
        ax.plot(
            t,
            _centred_mean(nominal[:, c] - meas[:, c], w),
            color="tab:red",
            lw=0.7,
            label="residual, nominal" + tag,
        )
        if current.effects:
            ax.plot(
                t,
                _centred_mean(aug[:, c] - meas[:, c], w),
                color="tab:blue",
                lw=0.7,
                label="residual, augmented" + tag,
            )
        ax.axhspan(-prep.sigma[c], prep.sigma[c], color="0.85", label="±1σ noise")
        if worst is not None and (worst.family, worst.condition) in masks:
            m = masks[(worst.family, worst.condition)]
            ax.fill_between(
                t,
                0,
                1,
                where=m,
                color="gold",
                alpha=0.3,
                transform=ax.get_xaxis_transform(),
                label=f"worst: {worst.condition}",
            )
        ax.set_ylabel(f"residual {name}")
        ax.legend(loc="upper right", fontsize=7)
    axes[-1].set_xlabel("t (s), held-out run")
    figs["overlay"] = _png(fig)
    # ranking
    eff = [e for e in result.to_json()["effects"] if e["held_out"]["closed_fraction"] is not None]
    fig, ax = plt.subplots(figsize=(8, 0.35 * len(eff) + 1))
    names = [e["id"] for e in eff][::-1]
    vals = [max(-0.2, e["held_out"]["closed_fraction"]) for e in eff][::-1]
    lo = [max(-0.2, e["held_out"]["interval"][0] or 0.0) for e in eff][::-1]
    hi = [e["held_out"]["interval"][1] or 0.0 for e in eff][::-1]
    colors = [
        "tab:blue" if e["selected"] else ("tab:green" if e["held_out"]["significant"] else "0.7") for e in eff
    ][::-1]
    ax.barh(
        names,
        vals,
        color=colors,
        xerr=[np.maximum(0, np.array(vals) - lo), np.maximum(0, np.array(hi) - vals)],
        capsize=2,
    )
    ax.set_xlabel("share of the held-out gap closed (alone), 95 % bootstrap interval")
    ax.axvline(0, color="k", lw=0.5)
    figs["ranking"] = _png(fig)
    # residual loops
    x = run.column(prep.spec.primary()[0])[start:]
    v = np.gradient(x, run.dt)
    fig, axes = plt.subplots(q, 2, figsize=(10, 3 * q), squeeze=False)
    for c, name in enumerate(prep.channel_names):
        for j, (sig, lab) in enumerate(((v, "velocity"), (x, "position"))):
            ax = axes[c, j]
            ax.plot(sig, nominal[:, c] - meas[:, c], color="tab:red", lw=0.4, alpha=0.7, label="nominal")
            if current.effects:
                ax.plot(sig, aug[:, c] - meas[:, c], color="tab:blue", lw=0.4, alpha=0.7, label="augmented")
            ax.set_xlabel(lab)
            ax.set_ylabel(f"residual {name}")
            ax.legend(fontsize=7)
    figs["loops"] = _png(fig)
    return figs


CSS = """
body{font-family:system-ui,sans-serif;max-width:1100px;margin:2em auto;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1.5em;font-size:0.9em}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:left}
th{background:#f0f0f0}.verdict{font-size:1.3em;padding:0.5em;background:#eef}
.flag{padding:0.5em;background:#fdd;border-left:4px solid #c00}
img{max-width:100%}code{background:#f5f5f5}
"""


def write_html(result: Diagnosis, path: str | Path) -> Path:
    """Write the HTML report (plots embedded)."""
    path = Path(path)
    doc = to_json(result)
    figs = _figures(result)
    sel = doc["selected"]
    parts = [
        f"<html><head><meta charset='utf-8'><title>cablekit "
        f"diagnosis</title><style>{CSS}</style></head><body>"
    ]
    parts.append("<h1>Sim-to-real gap diagnosis</h1>")
    ho = sel["held_out"]
    parts.append(
        f"<p class='verdict'>Verdict: <b>{doc['verdict'].replace('_', ' ')}</b>. "
        + (
            f"Selected: <b>{', '.join(sel['effects'])}</b>; held-out gap {_fmt(ho['gap_before'])} → "
            f"{_fmt(ho['gap_after'])} "
            f"(noise = 1), {_fmt(100 * ho['closed_fraction'], 3)} % closed "
            f"[{_fmt(100 * (ho['interval'][0] or 0), 3)}, {_fmt(100 * (ho['interval'][1] or 0), 3)}]."
            if sel["effects"]
            else f"Held-out gap {_fmt(doc['gap']['held_out'])} in noise units (1 = measurement noise only)."
        )
        + "</p>"
    )
    for f in doc["flags"]:
        parts.append(f"<p class='flag'>⚠ {html.escape(f)}</p>")
    amb = doc.get("ambiguity")
    if amb:
        parts.append(
            f"<p class='flag'>Ambiguous between <b>{html.escape(amb['between'][0])}</b> and "
            f"<b>{html.escape(amb['between'][1])}</b>: {html.escape(amb['experiment'])}</p>"
        )
    for u in doc.get("unexplained", []):
        parts.append(f"<p class='flag'>Unexplained: {html.escape(u)}</p>")
    if sel["effects"]:
        rows = [
            [
                c["channel"],
                _fmt(c["gap_before"]),
                _fmt(c["gap_after"]),
                f"{100 * c['change']:+.0f} %",
                "WORSE" if c["worsened"] else "",
            ]
            for c in sel["channels_held_out"]
        ]
        parts.append("<p>Held-out gap per channel (noise units) with the selected effects:</p>")
        parts.append(_table(rows, ["channel", "nominal", "selected", "change", "flag"]))
    parts.append(
        "<h2>Where the gap lies</h2><p>Residual energy by operating condition (held-out runs), "
        "most concentrated first:</p>"
    )
    rows = [
        [
            c["family"],
            c["condition"],
            f"{100 * c['time_share']:.0f} %",
            f"{100 * c['energy_share']:.0f} %",
            f"{c['concentration']:.2f}",
        ]
        for c in doc["where"]["conditions_held_out"][:10]
    ]
    parts.append(_table(rows, ["family", "condition", "time", "residual energy", "concentration"]))
    rows = [
        [
            ch,
            t["reading"],
            f"{t['whiteness']['outside']}/{t['whiteness']['lags']}",
            f"{t['input_correlation']['outside']}",
            _fmt(t["loop_area_velocity"]),
            _fmt(t["loop_area_position"]),
        ]
        for ch, t in doc["where"]["residual_tests"].items()
    ]
    parts.append(
        _table(
            rows,
            [
                "channel",
                "reading",
                "ACF lags outside 99 % band",
                "CCF lags outside",
                "loop area vs velocity",
                "loop area vs position",
            ],
        )
    )
    parts.append(
        "<h2>Which effect</h2><p>Each candidate fitted alone on the fit runs, scored on the "
        "held-out runs.</p>"
    )
    if "ranking" in figs:
        parts.append(_img(figs["ranking"], "ranking"))
    rows = []
    for e in doc["effects"]:
        h = e["held_out"]
        params = "; ".join(f"{p['name']}={_fmt(p['value'])} {p['unit']}" for p in e["parameters"])
        ident = "; ".join(
            f"collinear with {n['with']} (cos {n['signature_cosine']:.2f}): {n['experiment']}"
            for n in e["identifiability"]
        )
        rows.append(
            [
                e["id"] + (" ✔" if e["selected"] else ""),
                _fmt(h["closed_fraction"]),
                f"[{_fmt(h['interval'][0])}, {_fmt(h['interval'][1])}]",
                "yes" if h["significant"] else "no",
                _fmt(e["fit"]["closed_fraction"]),
                params,
                ident or e.get("error") or "",
            ]
        )
    parts.append(
        _table(
            rows,
            [
                "effect",
                "held-out closed",
                "95 % interval",
                "significant",
                "fit closed",
                "parameters",
                "notes",
            ],
        )
    )
    if doc["skipped"]:
        parts.append(
            "<p>Not tried: "
            + "; ".join(f"<code>{k}</code> ({v})" for k, v in doc["skipped"].items())
            + "</p>"
        )
    parts.append("<h2>How far it closes</h2>")
    if sel["parameters"]:
        rows = [
            [
                p["effect"],
                p["name"],
                _fmt(p["value"], 4),
                p["unit"],
                "–" if p["ci95"] is None else f"[{_fmt(p['ci95'][0])}, {_fmt(p['ci95'][1])}]",
            ]
            for p in sel["parameters"]
        ]
        parts.append(_table(rows, ["effect", "parameter", "value", "unit", "95 % CI"]))
    pc = sel["per_channel"]
    rows = [
        [
            ch,
            pc["fit_before"][ch]["unit"],
            _fmt(pc["fit_before"][ch]["rmse"]),
            _fmt(pc["fit_after"][ch]["rmse"]),
            _fmt(pc["held_out_before"][ch]["rmse"]),
            _fmt(pc["held_out_after"][ch]["rmse"]),
        ]
        for ch in pc["fit_before"]
    ]
    parts.append(
        _table(rows, ["channel", "unit", "RMSE fit before", "fit after", "held-out before", "held-out after"])
    )
    rows = [
        [
            c["family"],
            c["condition"],
            _fmt(c["energy_before"]),
            _fmt(c["energy_after"]),
            f"{100 * c['reduction']:.0f} %",
        ]
        for c in sel["per_condition_held_out"][:12]
    ]
    parts.append(_table(rows, ["family", "condition", "residual energy before", "after", "reduction"]))
    parts.append(
        f"<p>Left unexplained on held-out data: excess gap {_fmt(sel['unexplained_gap'])} (noise units).</p>"
    )
    if "overlay" in figs:
        parts.append("<h3>Held-out run: before and after</h3>" + _img(figs["overlay"], "overlay"))
    if "loops" in figs:
        parts.append("<h3>Residual loops (hysteresis shows as area)</h3>" + _img(figs["loops"], "loops"))
    parts.append(
        "<h2>Run metadata</h2><pre>" + html.escape(json.dumps(doc["meta"], indent=1)[:6000]) + "</pre>"
    )
    parts.append("</body></html>")
    path.write_text("\n".join(parts))
    return path
