"""``cablekit cdpr``: the workspace of a robot file, and tensions along a trajectory."""

from __future__ import annotations

import argparse
import csv
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cablekit.cdpr import Robot, Winch, shipped, shipped_names
from cablekit.cdpr.formats import read_trajectory
from cablekit.cdpr.workspace import DEFAULT_COUNTS, Requirement, plot_workspace, workspace
from cablekit.cli._options import outputs
from cablekit.errors import DataError

if TYPE_CHECKING:
    from cablekit.cdpr.diagnose import CdprDiagnosis


def robot_from(spec: str) -> Robot:
    """A robot file's path, or the name of a shipped robot."""
    p = Path(spec)
    if p.suffix == ".toml" or p.exists():
        return Robot.load(p)
    names = shipped_names()
    if spec in names:
        r = shipped(spec)
        assert isinstance(r, Robot)
        return r
    raise DataError(f"{spec!r} is neither a robot file nor a shipped robot ({', '.join(names)})")


def _export_mjcf(args: argparse.Namespace) -> int:
    from importlib import resources

    from cablekit.cdpr.mjcf import export_mjcf

    robot = robot_from(args.robot)  # a robot file, or a shipped robot's name (else the error)
    path = Path(args.robot)
    if not (path.suffix == ".toml" or path.exists()):
        path = Path(str(resources.files("cablekit.cdpr") / "robots" / f"{args.robot}.toml"))
    out = export_mjcf(path, args.out or f"{path.stem}.xml")
    print(
        f"wrote {out}: the platform on a {'planar' if robot.motion == 'planar' else 'free'} "
        "joint, a spatial tendon per cable (over its swivelling pulley where it has one) and a tendon motor "
        "whose control is the cable's tension (N); cablekit.cdpr.mjcf.mujoco_state(robot, pose) gives qpos"
    )
    return 0


def _floats(text: str | None, n: int, name: str) -> np.ndarray | None:
    if text is None:
        return None
    try:
        v = np.array([float(s) for s in text.split(",")])
    except ValueError:
        raise DataError(f"--{name} must be {n} comma-separated numbers, got {text!r}") from None
    if v.shape != (n,):
        raise DataError(f"--{name} must be {n} comma-separated numbers, got {text!r}")
    return v


def _workspace(args: argparse.Namespace) -> int:
    robot = robot_from(args.robot)
    n = robot.dof
    k = 2 if robot.motion == "planar" else 3
    req = Requirement(
        gravity=not args.no_gravity,
        wrench=_floats(args.wrench, n, "wrench"),
        half_width=_floats(args.half_width, n, "half-width"),
        moment_length=args.moment_length,
        margins=args.margins,
    )
    ws = workspace(
        robot,
        counts=args.counts,
        lower=_floats(args.lower, k, "lower"),
        upper=_floats(args.upper, k, "upper"),
        orientation=_floats(args.orientation, n - k, "orientation"),
        requirement=req,
    )
    out = ws.save(args.out)
    plots = [] if args.no_plots else plot_workspace(ws, out, robot)
    print(ws.table(), end="")
    print(f"wrote {out / 'workspace.npz'}, {out / 'workspace.md'}" + "".join(f", {p}" for p in plots))
    return 0


def _distribute(args: argparse.Namespace) -> int:
    robot = robot_from(args.robot)
    tr = read_trajectory(args.trajectory, robot.motion)
    res = robot.distribute(tr.poses, tr.wrenches, method=args.method, gravity=not args.no_gravity)
    f = res.f
    jump = np.concatenate([[0.0], np.abs(np.diff(f, axis=0)).max(axis=1)]) if len(f) else np.zeros(0)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "tensions.csv"
    with path.open("w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        lead = ["t"] if tr.t is not None else []
        w.writerow(
            [*lead, *(f"f{i + 1}" for i in range(robot.n_cables)), "method", "feasible", "residual", "jump"]
        )
        for i in range(len(f)):
            t = [f"{tr.t[i]:.9g}"] if tr.t is not None else []
            w.writerow(
                [
                    *t,
                    *(f"{v:.9g}" for v in f[i]),
                    res.method[i],
                    int(res.feasible[i]),
                    f"{res.residual[i]:.3e}",
                    f"{jump[i]:.6g}",
                ]
            )
    methods = {m: res.method.count(m) for m in dict.fromkeys(res.method)}
    feasible_jump = jump[1:][res.feasible[1:] & res.feasible[:-1]] if len(f) > 1 else np.zeros(0)
    largest = feasible_jump.max() if feasible_jump.size else 0.0
    lines = [
        "| quantity | value |",
        "|---|---|",
        f"| robot | {robot.name} |",
        f"| poses | {len(f)} |",
        f"| method asked | {args.method} |",
        f"| answered by | {', '.join(f'{m}: {c}' for m, c in methods.items())} |",
        f"| feasible | {int(res.feasible.sum())} of {len(f)} |",
        f"| largest residual ‖Aᵀf + w‖ | {res.residual.max():.3e} |",
        f"| largest jump between feasible neighbours (N) | {largest:.4g} |",
        f"| largest jump overall (N) | {jump.max():.4g} |",
    ]
    (out / "tensions.md").write_text("\n".join(lines) + "\n", encoding="utf-8")
    print("\n".join(lines))
    if not args.no_plots:
        from cablekit.plotting import pyplot_or_none

        plt = pyplot_or_none()
        if plt is not None:
            x = tr.t if tr.t is not None else np.arange(len(f))
            fig, ax = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
            ax[0].plot(x, f)
            lo, hi = robot.bounds
            ax[0].axhline(lo.min(), color="k", ls=":")
            ax[0].axhline(hi.max(), color="k", ls=":")
            bad = ~res.feasible
            if bad.any():
                ax[0].plot(x[bad], f[bad].max(axis=1), "rx", label="infeasible")
                ax[0].legend()
            ax[0].set_ylabel("tension (N)")
            ax[0].set_title(f"{robot.name}: tensions along the trajectory ({args.method})")
            ax[1].semilogy(x, np.maximum(jump, 1e-12))
            ax[1].set_ylabel("largest |Δf| (N)")
            ax[1].set_xlabel("t (s)" if tr.t is not None else "pose")
            fig.tight_layout()
            fig.savefig(out / "tensions.png", dpi=100)
            plt.close(fig)
    print(f"wrote {path}")
    return 0


def _winch(args: argparse.Namespace) -> int:
    from cablekit.cdpr.winch import report

    return _reported(args, report(args.out, plots=not args.no_plots), "winch.md")


def _planar(args: argparse.Namespace) -> int:
    from cablekit.cdpr.planar import report

    return _reported(args, report(args.out, plots=not args.no_plots), "planar.md")


def _reported(args: argparse.Namespace, text: str, name: str) -> int:
    """Print a report written to ``args.out/name`` (unless ``--quiet``) and where it went."""
    if not args.quiet:
        print(text)
    print(f"wrote {Path(args.out) / name}")
    return 0


def _winch_with(text: str | None) -> Winch:
    """Seed 003's winch with ``name=value,...`` overrides."""
    values = dict(zip(Winch.NAMES, Winch.seed003().values, strict=True))
    for item in (text or "").split(","):
        if not item.strip():
            continue
        name, _, value = item.partition("=")
        name = name.strip()
        if name not in values:
            raise DataError(f"--winch: unknown parameter {name!r}; known: {', '.join(Winch.NAMES)}")
        try:
            values[name] = float(value)
        except ValueError:
            raise DataError(f"--winch: {name} must be a number, got {value!r}") from None
    return Winch(np.array(list(values.values())))


def _diagnose_run(args: argparse.Namespace) -> int:
    from cablekit.cdpr.diagnose import diagnose_file, diagnose_runs

    robot = robot_from(args.robot)
    friction, topics = None, None
    if Path(args.robot).suffix == ".toml" or Path(args.robot).exists():
        from cablekit._files import parse_toml, read_text
        from cablekit.cdpr import path_friction_of, topics_of

        doc = parse_toml(read_text(args.robot, "robot file"), str(args.robot))
        friction, topics = path_friction_of(doc, str(args.robot)), topics_of(doc, str(args.robot))
    if args.platform_friction is not None:
        mu, visc, wrap, presliding = _floats(args.platform_friction, 4, "platform-friction")
        m = robot.n_cables
        friction = {
            "coefficient": np.full(m, mu),
            "viscous": np.full(m, visc),
            "guide_wrap": np.full(m, wrap),
            "presliding": presliding,
        }
    winch = _winch_with(args.winch_parameters)
    if (args.holdout or len(args.run) == 1) and _drives_diagnosis(args, robot, winch, friction, topics):
        return 0
    if args.holdout:
        d = diagnose_runs(args.run, args.holdout, robot, winch, platform_side=friction, topics=topics)
    elif len(args.run) == 1:
        d = diagnose_file(args.run[0], robot, winch, platform_side=friction, topics=topics)
    else:
        raise DataError("several --run files need --holdout runs (one run alone is split in halves)")
    write_run_diagnosis(robot, d, args.run, args.holdout, Path(args.out), args.quiet, plots=not args.no_plots)
    return 0


def _drives_diagnosis(
    args: argparse.Namespace, robot: Robot, winch: Any, friction: Any, topics: Any = None
) -> bool:
    """With measured poses in every run: the drives as a network through the one engine
    (:mod:`cablekit.cdpr.drives`; ``diagnosis.json`` and ``.html``), a lone run fitted on its
    first half and scored on its second. ``False`` (nothing done) without poses."""
    from types import SimpleNamespace

    from cablekit.cdpr.drives import drive_runs
    from cablekit.cdpr.formats import RunFile, load_cdpr_run
    from cablekit.cli.diagnose import _run_diagnosis

    paths = [*args.run, *(args.holdout or [])]
    runs = [(Path(p).name, load_cdpr_run(p, robot, topics=topics)) for p in paths]
    if any(r.poses is None for _, r in runs):
        return False
    if not args.holdout:
        (name, r), h = runs[0], len(runs[0][1].t) // 2
        half = [slice(0, h), slice(h, None)]
        runs = [
            (
                f"{name} ({which} half)",
                RunFile(r.t[s], r.alpha[s], r.current[s], r.sensor[s], r.poses[s], r.notes),
            )
            for which, s in zip(("first", "second"), half, strict=True)
        ]
    n_fit = len(args.run) if args.holdout else 1
    spec, loaded = drive_runs(robot, winch, runs, friction)
    opts = SimpleNamespace(workers=0, seed=0, intervals=0, no_html=args.no_plots, quiet=args.quiet)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    _run_diagnosis(
        spec, loaded[:n_fit], loaded[n_fit:], out, opts, f"{robot.name} (its drives at the measured poses)"
    )  # type: ignore[arg-type]
    return True


def write_run_diagnosis(
    robot: Robot,
    d: CdprDiagnosis,
    fit: list[str],
    holdout: list[str] | None,
    out: Path,
    quiet: bool,
    *,
    plots: bool = True,
) -> None:
    """``diagnose.md`` (and ``diagnose.png``) of a run diagnosis (also ``cablekit diagnose`` with a
    robot file)."""
    from cablekit.cdpr.diagnose import plot, run_report

    out.mkdir(parents=True, exist_ok=True)
    fig = plot(d, out / "diagnose.png") if plots else None
    _write_text(out, run_report(robot.name, d, fit, holdout, fig.name if fig else None), quiet)


def _write_diagnosis(args: argparse.Namespace, text: str) -> None:
    _write_text(Path(args.out), text, args.quiet)


def _write_text(out: Path, text: str, quiet: bool) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / "diagnose.md").write_text(text, encoding="utf-8")
    if not quiet:
        print(text)
    print(f"wrote {out / 'diagnose.md'}")


def _diagnose(args: argparse.Namespace) -> int:
    from cablekit.cdpr.selftest import markdown, self_test
    from cablekit.diagnose.report import write_html, write_json

    if args.run is not None:
        if args.robot is None:
            raise DataError("--run needs --robot (a robot file or a shipped robot's name)")
        return _diagnose_run(args)
    effects = tuple(args.effects.split(",")) if args.effects else None
    cases = self_test(
        cases=args.cases, seed=args.seed, duration=args.duration, effects=effects, progress=not args.quiet
    )
    out = Path(args.out)
    (out / "cases").mkdir(parents=True, exist_ok=True)
    links = []
    for c in cases:
        name = "nothing" if c.effect is None else f"{c.effect}-cable{c.cable + 1}"
        name += f"-{len(links) + 1}"
        write_json(c.diagnosis, out / "cases" / f"{name}.json")
        if not args.no_plots:
            write_html(c.diagnosis, out / "cases" / f"{name}.html")
            links.append(f"[{name}](cases/{name}.html)")
    text = (
        "# The parallel robot's drives in the diagnosis engine: self-test on the Mini CDPR twin\n\n"
        f"Each run {args.duration:g} s (its first half fitted, its second held out); the engine's "
        "intervals, screening and identifiability are in each case's report"
        + (": " + ", ".join(links) if links else "")
        + ".\n\n"
    )
    _write_diagnosis(args, text + markdown(cases) + "\n")
    return 0 if all(c.correct_site for c in cases) else 1


def _compensate(args: argparse.Namespace) -> int:
    from cablekit.cdpr import force
    from cablekit.cdpr.compensate import compensate, report

    comp = compensate(hidden=args.hidden, epochs=args.epochs, seed=args.seed, progress=not args.quiet)
    text = report(args.out, comp, plots=not args.no_plots)
    fc = force.force_control(comp.network, seed=args.seed, epochs=args.epochs, progress=not args.quiet)
    extra = (
        "\n## Force control (seed 002 §§4–5) on the twin as a dynamic plant\n\n" + force.markdown(fc) + "\n"
    )
    if not args.no_plots and (fig := force.plot(Path(args.out) / "force_control.png", fc)):
        extra += f"\n![force loop along test 1]({fig.name})\n"
    with open(Path(args.out) / "compensate.md", "a", encoding="utf-8") as f:
        f.write(extra)
    text += extra
    if not args.quiet:
        print(text)
    print(f"wrote {Path(args.out) / 'compensate.md'}")
    return 0


def add_parser(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """``cablekit cdpr workspace``, ``distribute``, ``winch``, ``planar``, ``diagnose``, ``compensate``
    and ``export-mjcf``."""
    p = sub.add_parser("cdpr", help="cable-driven parallel robots: workspace, tensions along a trajectory")
    cs = p.add_subparsers(dest="cdpr_command", required=True)
    w = cs.add_parser(
        "workspace",
        help="static or wrench-feasible workspace on a grid: map (npz), table (md), plots",
        description="The capacity margin (distance to the edge of the available wrench set) on a grid of "
        "positions at a fixed orientation; the static workspace by default, the wrench-feasible one with "
        "--wrench/--half-width.",
    )
    w.add_argument("robot", help="robot TOML file, or a shipped robot: " + ", ".join(shipped_names()))
    w.add_argument("--out", required=True, help="output folder")
    w.add_argument("--counts", type=int, default=DEFAULT_COUNTS, help="grid points per position axis")
    w.add_argument("--lower", help="grid's lower corner, comma-separated (default: the anchors' box)")
    w.add_argument("--upper", help="grid's upper corner, comma-separated")
    w.add_argument("--orientation", help="fixed orientation: theta (planar) or roll,pitch,yaw (rad)")
    w.add_argument("--wrench", help="centre of the required external wrench box, n comma-separated values")
    w.add_argument("--half-width", help="half widths of the required wrench box, n comma-separated values")
    w.add_argument("--moment-length", type=float, default=1.0, help="moments count as moment / length (m)")
    w.add_argument(
        "--margins",
        choices=("everywhere", "inside"),
        default="everywhere",
        help="where margins are exact: inside stops an outside pose at its first crossed facet (faster)",
    )
    w.add_argument("--no-gravity", action="store_true", help="leave out the platform's weight")
    w.add_argument("--no-plots", action="store_true", help="no PNGs (no matplotlib needed)")
    w.set_defaults(func=_workspace)
    d = cs.add_parser(
        "distribute",
        help="tensions along a trajectory CSV, the method per pose and the jumps",
        description="Columns: the pose (planar x,y,theta; spatial x,y,z,roll,pitch,yaw), optionally the "
        "external wrench (planar fx,fy,mz; spatial fx,fy,fz,mx,my,mz) and t.",
    )
    d.add_argument("robot", help="robot TOML file, or a shipped robot")
    d.add_argument("--trajectory", required=True, help="trajectory CSV")
    d.add_argument("--out", required=True, help="output folder")
    d.add_argument(
        "--method",
        default="auto",
        choices=["auto", "improved_closed_form", "closed_form", "qp", "least_wrench_error", "minimum_norm"],
        help="tension distribution: auto takes the improved closed form and falls back to the QP, then "
        "to the least wrench error where no tensions within the bounds hold the platform",
    )
    d.add_argument("--no-gravity", action="store_true", help="leave out the platform's weight")
    d.add_argument("--no-plots", action="store_true", help="no PNGs (no matplotlib needed)")
    d.set_defaults(func=_distribute)
    wn = cs.add_parser(
        "winch",
        help="a winch under PID (motor, gearbox, drum, elastic cable): its linearised poles and root "
        "locus (seed 003 Table 5), the nonlinear model stepped, the load-cell pulleys and their calibration",
    )
    outputs(wn, "out/winch")
    wn.set_defaults(func=_winch)
    pl = cs.add_parser(
        "planar",
        help="a planar 4-cable robot with PID winches in closed loop (seed 003): pose steps and a "
        "circle, the tension distribution in the loop",
    )
    outputs(pl, "out/planar")
    pl.set_defaults(func=_planar)
    dg = cs.add_parser(
        "diagnose",
        help="locate pulley friction, sensor lag, a calibration error (motor current vs sensor) or cable "
        "creep, elasticity, a length offset (cable lengths vs measured poses) per cable: in a run file "
        "(--run), or a self-test on the plant with withheld effects (exit 1 on a miss)",
    )
    dg.add_argument(
        "--run",
        nargs="+",
        help="run table(s): t, alpha_j, current_j, sensor_j (j = 1..m) and optionally the pose columns; "
        "one run alone is fitted on its first half and scored on its second",
    )
    dg.add_argument("--holdout", nargs="+", help="with --run: held-out run table(s), never fitted")
    dg.add_argument("--no-plots", action="store_true", help="with --run: no PNG (no matplotlib needed)")
    dg.add_argument("--robot", help="with --run: a robot file or a shipped robot's name")
    dg.add_argument(
        "--winch",
        dest="winch_parameters",
        help="with --run: the winch's parameters (motor, gearbox, drum; seed 003's by default) with "
        "overrides, e.g. drum_radius=0.02,gear_ratio=51",
    )
    dg.add_argument(
        "--platform-friction",
        help="with --run: the nominal pulley friction between sensor and platform, every cable: "
        "friction coefficient, viscous coefficient, wrap angle of the guide pulley (rad) and the Dahl "
        "pre-sliding length (m): mu,viscous,guide_wrap,presliding (seed 002 eq. 8); default: the robot "
        "file's [path_friction] table, else none",
    )
    dg.add_argument("--out", default="out/cdpr-diagnose", help="output folder")
    dg.add_argument("--cases", type=int, default=2, help="runs per withheld effect (and with none)")
    dg.add_argument("--duration", type=float, default=30.0, help="seconds of each twin run (4 to 30)")
    dg.add_argument(
        "--effects",
        help="withhold only these (comma-separated: pulley_friction, sensor_lag, sensor_gain, drum_friction, "
        "cable_elasticity, cable_creep); the controls always run",
    )
    dg.add_argument("--seed", type=int, default=0, help="cables, excitation and noise")
    dg.add_argument("--quiet", action="store_true", help="no table or progress on stdout")
    dg.set_defaults(func=_diagnose)
    cp = cs.add_parser(
        "compensate",
        help="pulley friction between a winch-side sensor and the platform: the tension the sensor "
        "reads against the platform's, a network that compensates it (seed 002 Tables 1-2), a force loop "
        "on its estimate (Tables 3-4)",
    )
    outputs(cp, "out/compensate")
    cp.add_argument("--hidden", type=int, default=20, help="hidden neurons")
    cp.add_argument("--epochs", type=int, default=300, help="Bayesian-regularisation epochs")
    cp.add_argument("--seed", type=int, default=0, help="noise, test points and training seed")

    cp.set_defaults(func=_compensate)
    mj = cs.add_parser(
        "export-mjcf",
        help="the robot as MuJoCo MJCF: platform body, anchor and attachment sites, a spatial tendon per "
        "cable (wrapping its swivelling pulley), a tendon motor per cable (control = tension, N)",
    )
    mj.add_argument("robot", help="robot TOML file, or a shipped robot: " + ", ".join(shipped_names()))
    mj.add_argument("--out", help="MJCF file to write (default: the robot file's name with .xml)")
    mj.set_defaults(func=_export_mjcf)
