"""The command line: ``zeroset reconstruct``, ``optimize``, ``render``, ``live``, ``demo``
and more."""

from __future__ import annotations

import argparse
import sys
import warnings
from dataclasses import fields
from pathlib import Path

__all__ = ["main"]

DEMO_POINTS = 40_000
#: Points on the demo's mesh whose distance to the true pipe it reports.
DEMO_SAMPLES = 100_000
HTML_SUFFIXES = (".html", ".htm")
#: Options renamed so that each has one meaning and names its units: (command, old): new.
RENAMED = {
    ("reconstruct", "--radius"): "--rho-delta",
    ("reconstruct", "--threshold"): "--threshold-mm",
    ("inspect", "--threshold"): "--threshold-mm",
    ("evaluate", "--points"): "--scan",
}


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the exit status (0 ok, 1 no surface or an internal
    error, 2 bad input, 3 a mesh that cannot be inspected as a pipe, after everything
    before the inspection is written).

    Every failure prints one line, ``zeroset: error: PATH: what is wrong``, and ``--debug``
    shows the traceback instead. Every change to the surface beyond Hoppe's method
    (`zeroset.SurfaceWarning`) prints one line, ``zeroset: warning: ...``, unless
    ``--quiet``. Messages from the pipeline, which knows no file names, get
    the path of the command's ``input``. Bad input is an `InputError` (or the system's
    `OSError`, or too little memory); any other exception, a ``ValueError`` from deep
    inside too, is a bug, reported as such with exit status 1.
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    command = next((arg for arg in argv if not arg.startswith("-")), None)
    for arg in argv:
        renamed = RENAMED.get((command, arg.split("=")[0]))
        if renamed is not None:
            print(f"zeroset: error: {arg.split('=')[0]} is now {renamed}", file=sys.stderr)
            return 2
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    from .errors import (
        InputError,
        InspectionError,
        ReconstructionError,
        SurfaceWarning,
        ZerosetError,
    )

    try:
        with warnings.catch_warnings():
            shown = warnings.showwarning

            def show(message, category, *where, **more):
                """A SurfaceWarning as one line, ``zeroset: warning: ...``."""
                if not issubclass(category, SurfaceWarning):
                    shown(message, category, *where, **more)
                elif not getattr(args, "quiet", False):
                    print(f"zeroset: warning: {message}", file=sys.stderr)

            warnings.showwarning = show
            warnings.simplefilter("always", SurfaceWarning)
            return args.run(args)
    except Exception as exc:
        if args.debug:
            raise
        message = " ".join(str(exc).split()) or type(exc).__name__
        expected = (ZerosetError, OSError, MemoryError)
        if isinstance(exc, MemoryError):
            message = f"out of memory ({message})"
        elif not isinstance(exc, expected):
            message = f"internal error, please report it: {type(exc).__name__}: {message}"
        paths = [v for value in vars(args).values() for v in _as_list(value) if isinstance(v, Path)]
        named = tuple(f"{path}: " for path in paths)
        source = getattr(args, "input", None)
        about_input = isinstance(exc, (InputError, ReconstructionError, MemoryError))
        if source is not None and about_input and not message.startswith(named):
            message = f"{', '.join(map(str, _as_list(source)))}: {message}"
        print(f"zeroset: error: {message}", file=sys.stderr)
        if isinstance(exc, InspectionError):
            return 3
        return 1 if isinstance(exc, ReconstructionError) or not isinstance(exc, expected) else 2


def _as_list(value) -> list:
    """`value` itself when a list (an argument with nargs), else a list holding it."""
    return value if isinstance(value, list) else [value]


def _parser() -> argparse.ArgumentParser:
    """The argument parser: one builder per command; no option is abbreviated."""
    from . import __version__

    parser = argparse.ArgumentParser(
        prog="zeroset",
        description="Triangle meshes from noisy point clouds (Hoppe 1992).",
        allow_abbrev=False,
    )
    parser.add_argument("--version", action="version", version=f"zeroset {__version__}")
    parser.set_defaults(command=None, debug=False)
    commands = parser.add_subparsers(title="commands")
    common = argparse.ArgumentParser(add_help=False, allow_abbrev=False)
    common.add_argument("--quiet", action="store_true", help="print nothing but errors")
    common.add_argument("--debug", action="store_true", help="show tracebacks")
    writes = argparse.ArgumentParser(add_help=False, allow_abbrev=False)
    writes.add_argument(
        "--force", action="store_true", help="replace output files that exist (never an input)"
    )
    for build in (
        _reconstruct_command,
        _optimize_command,
        _render_command,
        _inspect_command,
        _demo_command,
        _synth_command,
        _evaluate_command,
        _live_command,
    ):
        build(commands, [common, writes])
    return parser


def _formats(kind: str) -> str:
    """The file suffixes zeroset reads (and writes) for `kind`: mesh, points or poses."""
    from . import io

    formats = {"mesh": io.MESH_FORMATS, "points": io.POINT_FORMATS, "poses": io.POSE_FORMATS}
    return " ".join(formats[kind])


def _reconstruct_command(commands, parents) -> None:
    """``zeroset reconstruct``: points (one file or several scans) to a mesh."""
    parser = commands.add_parser(
        "reconstruct",
        allow_abbrev=False,
        parents=parents,
        help="reconstruct a mesh from points",
        description="Reconstruct a triangle mesh from a point cloud file, or from several scans.",
    )
    parser.add_argument(
        "input",
        type=Path,
        nargs="+",
        help="points: " + _formats("points") + "; several scans are merged into one",
    )
    parser.add_argument(
        "-o", "--output", type=Path, required=True, help="mesh: " + _formats("mesh")
    )
    parser.add_argument(
        "--poses",
        type=Path,
        help="pose of each scan: " + _formats("poses") + " (Stanford bmesh lines, or 4x4 "
        "matrices by scan file name or in order); each scan's sensor sits at its frame's "
        "origin unless --viewpoint says where",
    )
    parser.add_argument(
        "--register",
        action="store_true",
        help="refine the poses by ICP (Generalized-ICP) against the other scans; print residuals",
    )
    parser.add_argument(
        "--tiles",
        help="reconstruct in tiles run as Dask tasks: auto, or NxMxK tiles per axis; each "
        "reads its own points, and the pieces are welded exactly",
    )
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="with --tiles: a dask.distributed scheduler (default: a local cluster)",
    )
    parser.add_argument(
        "--workers",
        type=int,
        help="with --tiles: worker processes of the local cluster (default: one per core)",
    )
    parser.add_argument(
        "--allow-gaps",
        action="store_true",
        help="with --tiles: leave out a tile whose fit fails, with a warning (default: stop)",
    )
    parser.add_argument(
        "--per-tile",
        action="store_true",
        help="with --tiles: -o names a folder, which gets one PLY mesh per tile and a "
        "manifest tiles.json of the tiles, their boxes and seams (default: one file)",
    )
    parser.add_argument(
        "--report",
        type=Path,
        help="write parameters, counts and timings: .json, or .html with a 3D viewer",
    )
    parser.add_argument("--preview", type=Path, help="write a PNG picture of the mesh")
    parser.add_argument("--ascii", action="store_true", help="write PLY as text instead of binary")
    parser.add_argument(
        "--optimize",
        action="store_true",
        help="run phase 2, mesh optimisation (Hoppe 1993), on every point left after --crop",
    )
    parser.add_argument(
        "--inspect",
        type=Path,
        metavar="DIR",
        help="inspect the mesh as a pipe (see 'zeroset inspect') and write the results to DIR",
    )
    _add_inspection_options(parser)
    _add_config_options(parser)
    parser.set_defaults(command="reconstruct", run=_run_reconstruct)


def _optimize_command(commands, parents) -> None:
    """``zeroset optimize``: phase 2 on a mesh and its points."""
    parser = commands.add_parser(
        "optimize",
        allow_abbrev=False,
        parents=parents,
        help="optimise a mesh against points (phase 2)",
        description="Optimise a triangle mesh against the points it approximates (Hoppe "
        "1993): edge collapse, split and swap and vertex fitting lower the energy "
        "distance^2 + c_rep x vertices + kappa x edge lengths^2.",
    )
    parser.add_argument("mesh", type=Path, help="starting mesh: " + _formats("mesh"))
    parser.add_argument("points", type=Path, help="points: " + _formats("points"))
    parser.add_argument(
        "-o", "--output", type=Path, required=True, help="mesh: " + _formats("mesh")
    )
    parser.add_argument("--report", type=Path, help="write parameters, energies and moves as JSON")
    parser.add_argument("--ascii", action="store_true", help="write PLY as text instead of binary")
    parser.add_argument("--c-rep", type=float, help="cost of a vertex (default: from the noise)")
    parser.add_argument(
        "--kappa", type=float, help="first spring constant (default: from the data)"
    )
    parser.add_argument(
        "--tolerance",
        type=float,
        help="keep the result within this distance of the starting mesh, fitted to it instead "
        "of the points (default: none)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the random move order")
    parser.set_defaults(command="optimize", run=_run_optimize)


def _render_command(commands, parents) -> None:
    """``zeroset render``: a PNG picture of a mesh."""
    parser = commands.add_parser(
        "render",
        allow_abbrev=False,
        parents=parents,
        help="draw a mesh as a PNG picture",
        description="Draw a mesh, shaded (outside blue, inside orange), from two views, "
        "off-screen, with its boundary edges in red and optionally the points, their normals "
        "and colours by distance to the points.",
    )
    parser.add_argument("mesh", type=Path, help="mesh: " + _formats("mesh"))
    parser.add_argument(
        "points",
        type=Path,
        nargs="?",
        help="points to draw: " + _formats("points"),
    )
    parser.add_argument("-o", "--output", type=Path, required=True, help="picture: .png")
    parser.add_argument(
        "--hide-points", action="store_true", help="use POINTS but do not draw them"
    )
    parser.add_argument("--normals", action="store_true", help="draw the normals POINTS carry")
    parser.add_argument(
        "--intensity", action="store_true", help="colour the points by the intensity they carry"
    )
    parser.add_argument(
        "--distance", action="store_true", help="colour the mesh by how far POINTS lie from it"
    )
    parser.add_argument("--no-boundaries", action="store_true", help="do not mark boundary edges")
    parser.add_argument("--size", default="1200x600", help="picture size WIDTHxHEIGHT in pixels")
    parser.set_defaults(command="render", run=_run_render)


def _inspect_command(commands, parents) -> None:
    """``zeroset inspect``: a pipe's centreline, deviation, ovality and defects."""
    parser = commands.add_parser(
        "inspect",
        allow_abbrev=False,
        parents=parents,
        help="inspect a pipe: centreline, deviation, ovality and defects",
        description="Fit a pipe's centreline and nominal diameter to its mesh, measure "
        "every vertex's (and point's) deviation from the nominal pipe and the ovality per "
        "station, and find the dents and bulges beyond the noise, and the joints. Writes "
        "defects.csv, joints.csv, ovality.csv, inspection.json, deviation-map.png (the "
        "unrolled wall), ovality.png, deviation.png (the mesh coloured by deviation) and "
        "report.html to DIR.",
    )
    parser.add_argument("mesh", type=Path, help="the pipe's wall: " + _formats("mesh"))
    parser.add_argument(
        "points",
        type=Path,
        nargs="?",
        help="the scan the mesh was made from (better depths and noise-based thresholds; "
        "with its sensor positions, depths fitted along the beams): " + _formats("points"),
    )
    parser.add_argument("-o", "--output", type=Path, required=True, metavar="DIR", help="folder")
    _add_inspection_options(parser)
    parser.set_defaults(command="inspect", run=_run_inspect)


def _demo_command(commands, parents) -> None:
    """``zeroset demo``: a built-in noisy pipe, reconstructed."""
    parser = commands.add_parser(
        "demo",
        allow_abbrev=False,
        parents=parents[:1],
        help="reconstruct a built-in noisy pipe",
        description="Reconstruct a simulated noisy open pipe (radius "
        "0.25 m, length 1 m, noise 2 mm) and write the results to a folder.",
    )
    parser.add_argument("--out", type=Path, default=Path("zeroset-demo"), help="output folder")
    parser.add_argument("--points", type=int, default=DEMO_POINTS, help="number of points")
    parser.add_argument("--seed", type=int, default=0, help="seed of the simulated scan")
    parser.set_defaults(command="demo", run=_run_demo)


def _synth_command(commands, parents) -> None:
    """``zeroset synth``: a seeded synthetic cloud and its true surface."""
    parser = commands.add_parser(
        "synth",
        allow_abbrev=False,
        parents=parents,
        help="write a synthetic cloud and its true surface",
        description="Write seeded synthetic points (PLY, with normals and, for scans, sensor "
        "positions) and the true surface beside them as <stem>-truth.ply; the damaged-* kinds "
        "and pipe-run also write their truth (defects, joints, centreline) as "
        "<stem>-truth.json. Clock angles are degrees clockwise looking along the pipe from its "
        "start, 12 o'clock (0) being +y (for pipe-run: up, +z at the start, carried along).",
    )
    parser.add_argument(
        "kind",
        choices=sorted([*SYNTH_KINDS, "inject"]),
        help="what to sample; inject: put --dent, --bulge and --joint into the points of SCAN",
    )
    parser.add_argument(
        "scan", nargs="?", type=Path, help="with inject: a real scan (" + _formats("points") + ")"
    )
    parser.add_argument("-o", "--output", type=Path, required=True, help="points file (.ply)")
    parser.add_argument(
        "--points",
        type=int,
        default=20_000,
        help="number of points (surfaces; scans: see --rotation-step)",
    )
    parser.add_argument(
        "--noise", type=float, default=0.0, help="Gaussian noise per axis in metres (surfaces)"
    )
    parser.add_argument(
        "--noise-scale",
        type=float,
        default=1.0,
        help="scale of the scanner's range noise model (scans)",
    )
    parser.add_argument(
        "--rotation-step",
        type=float,
        default=1.0,
        help="degrees between scan lines (scans); 1 gives ~184k points per station",
    )
    parser.add_argument("--radius", type=float, help="pipe or sphere radius in metres")
    parser.add_argument(
        "--length", type=float, help="pipe length in metres (cylinder, tee, straight pipes)"
    )
    for kind in ("dent", "bulge"):
        parser.add_argument(
            f"--{kind}",
            action="append",
            default=[],
            metavar="AXIAL,CLOCK,DEPTH,WIDTH",
            help=f"add a {kind} (damaged-*, inject): centre at AXIAL metres along the "
            f"centreline and CLOCK degrees, DEPTH and WIDTH (patch diameter) in metres; "
            f"repeatable",
        )
    inject = parser.add_argument_group(
        "inject",
        "known truth put into a real scan: positions are the inspection's (metres along the "
        "centreline fitted to the scan from where its data start, clock degrees from 12 "
        "o'clock, the world's up); the points move along their beams where the scan has "
        "sensor positions, else towards the axis; the truth goes to <stem>-truth.json",
    )
    inject.add_argument(
        "--joint",
        action="append",
        default=[],
        metavar="KIND,AXIAL,SIZE[,CLOCK[,DEPTH]]",
        help="add a joint: gap (SIZE its axial width, DEPTH its recess, default 0.01), "
        "offset (SIZE its sideways step towards CLOCK) or bead (SIZE its height into the "
        "bore), metres; repeatable",
    )
    inject.add_argument(
        "--mesh", type=Path, help="the scan's mesh to fit the pipe to (default: reconstructed)"
    )
    inject.add_argument(
        "--up", type=_number_list(3), metavar="x,y,z", help="the world's up (default: 0,0,1)"
    )
    parser.add_argument(
        "--ovality",
        metavar="VALUE[,CLOCK]",
        help="(D_max - D_min) / D of the whole pipe, major axis at CLOCK degrees "
        "(default 0) (damaged-*, pipe-run)",
    )
    parser.add_argument(
        "--stations",
        metavar="S0,S1,...",
        help="scanner positions in metres along the centreline (damaged-pipe-scan, "
        "damaged-elbow-scan; default: the centreline's middle)",
    )
    run = parser.add_argument_group(
        "pipe-run",
        "a random run (0.4 m diameter, starting along +x), scanned at stations 0.5-1.5 m apart",
    )
    run.add_argument("--bends", metavar="MIN,MAX", help="how many bends (default: 2,4)")
    run.add_argument(
        "--out-of-plane", action="store_true", help="let the bends leave the horizontal plane"
    )
    run.add_argument("--tee", action="store_true", help="add a branch on a straight leg")
    run.add_argument(
        "--defects", type=int, default=0, metavar="K", help="add K random dents and bulges"
    )
    run.add_argument(
        "--joints", action="store_true", help="add gaps, offsets and beads every 1-3 m"
    )
    run.add_argument(
        "--uniform",
        type=int,
        metavar="N",
        help="write N points sampled uniformly on the wall instead of the scan",
    )
    parser.add_argument("--outliers", type=float, default=0.0, help="share of uniform outliers")
    parser.add_argument("--seed", type=int, default=0, help="seed")
    parser.set_defaults(command="synth", run=_run_synth)


def _evaluate_command(commands, parents) -> None:
    """``zeroset evaluate``: a mesh against a reference and the scan points."""
    parser = commands.add_parser(
        "evaluate",
        allow_abbrev=False,
        parents=parents,
        help="measure a mesh against a reference and/or points",
        description="Report a mesh's quality (manifoldness, boundary loops, triangle shape) "
        "and, when given, its distance to a reference surface (Chamfer, Hausdorff, F-score, "
        "normal consistency) and to the scan points (distances, coverage).",
    )
    parser.add_argument("mesh", type=Path, help="mesh to evaluate: " + _formats("mesh"))
    parser.add_argument("--reference", type=Path, help="true surface (a mesh)")
    parser.add_argument("--scan", type=Path, help="the scan's points the mesh was made from")
    parser.add_argument(
        "--samples",
        type=int,
        default=100_000,
        help="points sampled on each surface (default: 100000)",
    )
    parser.add_argument(
        "--tau",
        type=float,
        action="append",
        help="F-score threshold as a fraction of the reference's bounding-box "
        "diagonal; repeatable (default: 0.01 and 0.005)",
    )
    parser.add_argument("--json", type=Path, help="also write the report as JSON")
    parser.add_argument("--seed", type=int, default=0, help="seed of the surface sampling")
    parser.set_defaults(command="evaluate", run=_run_evaluate)


#: ``zeroset synth`` kinds: generator name in zeroset.synthetic, and whether it takes n.
SYNTH_KINDS = {
    "cylinder": "sample_cylinder",
    "sphere": "sample_sphere",
    "torus": "sample_torus",
    "two-spheres": "two_spheres",
    "elbow": "sample_elbow",
    "tee": "sample_tee",
    "pipe-scan": "scan_pipe",
    "damaged-pipe": "damaged_pipe",
    "damaged-elbow": "damaged_pipe",
    "damaged-pipe-scan": "scan_damaged_pipe",
    "damaged-elbow-scan": "scan_damaged_pipe",
    "pipe-run": "random_pipe_run",
}


def _live_command(commands, parents) -> None:
    """``zeroset live``: scans given one at a time, the mesh written block by block."""
    parser = commands.add_parser(
        "live",
        allow_abbrev=False,
        parents=parents,
        help="reconstruct scan by scan, as a robot scans, writing finished blocks",
        description="Replay scans one at a time (one file a scan, or one cloud split into "
        "its scans), or follow a folder a robot writes them into; each block of the "
        "mesh is written as soon as no later scan can reach it.",
    )
    parser.add_argument(
        "input", type=Path, nargs="*", help="scans: " + _formats("points") + ", each with "
        "its sensor positions (vp_x vp_y vp_z); one file is split into its scans",
    )  # fmt: skip
    parser.add_argument(
        "-o", "--output", type=Path, required=True, help="folder: one PLY mesh a block, "
        "the manifest tiles.json (read back by zeroset.tile_output.read_tile_meshes) and "
        "live.json (what was chosen, each scan's seconds, the counts)",
    )  # fmt: skip
    parser.add_argument(
        "--split-by", metavar="sensor|NAME", help="one input is cut into scans by its sensor "
        "positions, or by a per-point PLY property or NPZ array NAME (a scan index or a "
        "time) (default: sensor)",
    )  # fmt: skip
    parser.add_argument(
        "--split-every", type=float, metavar="X", help="by sensor: a new scan where the "
        "sensor has moved this far; by NAME: a scan for each span of X of it (default: "
        "each value of NAME a scan)",
    )  # fmt: skip
    parser.add_argument(
        "--follow", type=Path, metavar="DIR", help="take the scan files written into DIR, "
        "in name order, once each holds still (after the inputs, if any)",
    )  # fmt: skip
    parser.add_argument(
        "--idle", type=float, default=60.0, metavar="SECONDS",
        help="with --follow: stop after this long without a new file (default: 60)",
    )  # fmt: skip
    parser.add_argument(
        "--reach", type=float, help="farthest a scan's point lies from its sensor: blocks "
        "beyond it from the newest sensor are finished (default: the longest range seen)",
    )  # fmt: skip
    parser.add_argument(
        "--max-jump", type=float, help="a scan whose sensor lies farther than this from the "
        "previous one's is skipped (default: the reach)",
    )  # fmt: skip
    parser.add_argument(
        "--block-cubes", type=int, default=None, help="cubes along each edge of a block "
        "(default: 40)",
    )  # fmt: skip
    parser.add_argument(
        "--preview", type=float, default=0.0, metavar="DISTANCE", help="re-mesh the open "
        "blocks the newest scan reached within this distance of its sensor (default: 0, none)",
    )  # fmt: skip
    parser.add_argument(
        "--inspect", type=Path, metavar="DIR", help="inspect the pipe as its blocks finish "
        "(live-inspection.json, live-defects.csv, live-joints.csv, live-ovality.csv, rewritten "
        "as each stretch is reported); once the scans are done, inspect the welded mesh with "
        "every scan's points, read again (see 'zeroset inspect'); write both to DIR",
    )  # fmt: skip
    _add_inspection_options(parser)
    _add_config_options(parser)
    parser.set_defaults(command="live", run=_run_live)


def _run_live(args: argparse.Namespace) -> int:
    """`zeroset live`: each scan to `LiveReconstruction.add`, then `close`; live.json."""
    import time

    import numpy as np
    from tqdm.auto import tqdm

    from . import io
    from .config import ReconstructionConfig
    from .errors import InputError
    from .live import BLOCK_CUBES, LiveReconstruction
    from .tile_output import MANIFEST, check_folder

    if not args.input and args.follow is None:
        raise InputError("give scan files, or --follow DIR")
    folder = check_folder(args.output)
    report_path = folder / "live.json"
    if (folder / MANIFEST).exists() or report_path.exists():
        if not args.force:
            raise InputError(f"{folder}: holds a mesh ({MANIFEST}); add --force to replace it")
        for old in [folder / MANIFEST, report_path, *folder.glob("block-*.ply")]:
            old.unlink(missing_ok=True)
    for source in args.input:
        io.check_input(source)
    if args.inspect is not None:
        from .inspect._pictures import picture_modules

        picture_modules()  # a missing extra stops the run here, not after it
        from .inspect import LIVE_FILES

        _check_outputs(_inspection_files(args.inspect, LIVE_FILES), args.input, force=args.force)
    config = ReconstructionConfig().with_overrides(**_config_overrides(args))
    growing = None
    if args.inspect is not None:
        from .inspect import UP, LiveInspection

        growing = LiveInspection(
            nominal_diameter=args.nominal_diameter,
            threshold=None if args.threshold_mm is None else args.threshold_mm / 1000.0,
            up=UP if args.up is None else args.up,
            folder=args.inspect,
            rng=config.seed,
        )
    live = LiveReconstruction(
        config,
        block_cubes=BLOCK_CUBES if args.block_cubes is None else args.block_cubes,
        reach=args.reach,
        max_jump=args.max_jump,
        folder=folder,
        preview=args.preview,
        inspection=growing,
    )
    seconds, names, files = [], [], []
    bar = tqdm(
        desc="scans", unit="scan", leave=False, disable=args.quiet or not sys.stderr.isatty()
    )
    start = time.perf_counter()
    for name, points, viewpoints in _live_scans(args, config, files):
        update = live.add(points, viewpoints)
        seconds.append(update.seconds)
        names.append(name)
        bar.update()
        done = "" if growing is None else f", inspected to {growing.inspected_to:.2f} m"
        bar.set_postfix_str(f"{live.summary()['blocks_finished']} blocks finished{done}")
    live.close()
    bar.close()
    stats = live.summary()
    parameters = live.parameters
    report = {
        "inputs": [str(p) for p in args.input],
        "followed": None if args.follow is None else str(args.follow),
        "scans": [{"name": n, "seconds": s} for n, s in zip(names, seconds, strict=True)],
        "skipped": [{"scan": k, "reason": why} for k, why in live.skipped],
        "parameters": None if parameters is None else {
            "rho_delta": parameters.rho_delta, "cube_size": parameters.cube_size,
            "noise": parameters.noise, "notes": list(parameters.notes),
        },
        "block_cubes": live.block_cubes,
        "lattice_origin": None if live.offset is None else live.offset.tolist(),
        "stats": stats,
        "timings": {k: v for k, v in live.timings.items() if k != "scans"},
        "total_seconds": time.perf_counter() - start,
    }  # fmt: skip
    io.write_json(report_path, report)
    if args.inspect is not None:
        mesh = live.mesh()
        clouds = [_live_cloud(path, config) for path in files]
        points = np.concatenate([c[0] for c in clouds])
        viewpoints = np.concatenate([c[1] for c in clouds])
        inspection, pictures = _inspect(args, mesh, points, viewpoints)
        _write_inspection(args, args.inspect, mesh, points, inspection, pictures)
    if not args.quiet:
        median = float(np.median(seconds)) if seconds else 0.0
        print(
            f"scans       {len(seconds)} given, {stats['scans_skipped']} skipped; "
            f"{stats['late_points']} late points left out; median {median:.2f} s a scan"
        )
        print(
            f"mesh        {stats['blocks_finished']} blocks, {stats['vertices']:,} vertices, "
            f"{stats['faces']:,} triangles, written to {folder} ({MANIFEST}, live.json)"
        )
        if growing is not None:
            print(
                f"inspected   {len(growing.stretches)} stretches as they finished, to "
                f"{growing.inspected_to:.2f} m: {len(growing.defects())} defects "
                f"(live-*.csv and live-inspection.json in {args.inspect})"
            )
    return 0


def _live_scans(args: argparse.Namespace, config, files: list):
    """(name, points, viewpoints) of each scan: the inputs' (one file split into its scans),
    then the files that appear in --follow's folder; each file read goes into `files`."""
    from .errors import InputError
    from .scans import follow, read_column, split_scans

    if len(args.input) == 1 and args.follow is None:
        points, viewpoints = _live_cloud(args.input[0], config)
        files.append(args.input[0])
        by = args.split_by or "sensor"
        column = None if by == "sensor" else read_column(args.input[0], by)
        for k, rows in enumerate(split_scans(viewpoints, column=column, every=args.split_every)):
            yield f"{args.input[0]}#{k}", points[rows], viewpoints[rows]
        return
    if args.split_by is not None:
        raise InputError("--split-by cuts one input file into scans; several are a scan each")
    for path in args.input:
        files.append(path)
        yield str(path), *_live_cloud(path, config)
    if args.follow is not None:
        from . import io

        for path in follow(args.follow, tuple(io.POINT_FORMATS), idle=args.idle, seen=args.input):
            files.append(path)
            yield str(path), *_live_cloud(path, config)


def _live_cloud(path: Path, config) -> tuple:
    """The points (N, 3) of a scan file and their sensor positions (N, 3): the file's, or
    ``--viewpoint`` for every point."""
    import numpy as np

    from . import io
    from .errors import InputError

    cloud = io.read_points(path)
    viewpoints = cloud.viewpoints
    if viewpoints is None and config.viewpoint is not None:
        viewpoints = np.broadcast_to(np.asarray(config.viewpoint, float), cloud.points.shape)
    if viewpoints is None:
        raise InputError(
            f"{path}: has no sensor positions (vp_x vp_y vp_z); a live scan needs them, "
            "or --viewpoint"
        )
    return cloud.points, viewpoints


def _add_inspection_options(parser: argparse.ArgumentParser) -> None:
    """Add the options of a pipe inspection (``inspect``, ``reconstruct --inspect``)."""
    group = parser.add_argument_group("inspection")
    group.add_argument(
        "--nominal-diameter", type=float, metavar="D", help="pipe's inner diameter, in the "
        "data's units (default: the median measured diameter)",
    )  # fmt: skip
    group.add_argument(
        "--threshold-mm", type=float, metavar="MM", help="smallest depth reported as a "
        "defect, in mm (default: 4.5 standard errors of the local noise)",
    )  # fmt: skip
    group.add_argument(
        "--up", type=_number_list(3), metavar="x,y,z", help="the world's up, where 12 o'clock "
        "is (default: 0,0,1; +y for a pipe that starts within 30 degrees of it)",
    )  # fmt: skip


def _add_config_options(parser: argparse.ArgumentParser) -> None:
    """Add one --option per ReconstructionConfig field, named after it, typed by its
    annotation: a bool is a --x/--no-x switch, a tuple comma-separated numbers."""
    import types
    import typing

    from .config import ReconstructionConfig

    hints = typing.get_type_hints(ReconstructionConfig)
    group = parser.add_argument_group("reconstruction parameters")
    for f in fields(ReconstructionConfig):
        names = [f"--{f.name.replace('_', '-')}"]
        if "flag" in f.metadata:
            names.append(f"--{f.metadata['flag']}")
        kind = hints[f.name]
        if isinstance(kind, types.UnionType):  # X | None: an option of type X
            kind = next(t for t in typing.get_args(kind) if t is not type(None))
        if kind is bool:
            group.add_argument(
                *names,
                dest=f.name,
                action=argparse.BooleanOptionalAction,
                default=argparse.SUPPRESS,
                help=f.metadata["help"] + f" (default: {'on' if f.default else 'off'})",
            )
            continue
        if typing.get_origin(kind) is tuple:
            count = len(typing.get_args(kind))
            convert = _number_list(count)
            metavar = "x,y,z" if count == 3 else "x0,y0,z0,x1,y1,z1"
        elif "choices" in f.metadata:
            convert, metavar = str, "{" + ",".join(f.metadata["choices"]) + "}"
        else:
            convert, metavar = kind, f.name.upper()
        default = f" (default: {f.default})" if f.default is not None else ""
        group.add_argument(
            *names,
            dest=f.name,
            type=convert,
            choices=f.metadata.get("choices"),
            default=argparse.SUPPRESS,
            metavar=metavar,
            help=f.metadata["help"] + default,
        )


def _number_list(count: int):
    """Argument type: `count` comma-separated numbers."""

    def parse(text: str) -> tuple[float, ...]:
        try:
            values = tuple(float(part) for part in text.split(","))
        except ValueError:
            values = ()
        if len(values) != count:
            raise argparse.ArgumentTypeError(
                f"expected {count} comma-separated numbers; got {text!r}"
            )
        return values

    return parse


def _config_overrides(args: argparse.Namespace) -> dict:
    """The ReconstructionConfig fields given on the command line."""
    from .config import ReconstructionConfig

    return {
        f.name: getattr(args, f.name) for f in fields(ReconstructionConfig) if hasattr(args, f.name)
    }


def _run_reconstruct(args: argparse.Namespace) -> int:
    import time
    from dataclasses import replace

    from . import io
    from ._kernels._ahead import late_kernels_ahead
    from .config import ReconstructionConfig
    from .errors import InputError
    from .pipeline import reconstruct

    if args.per_tile:
        _check_tile_folder(args)
    _check_outputs(
        [None if args.per_tile else args.output, args.report, args.preview,
         *_inspection_files(args.inspect)],
        [*args.input, args.poses],
        force=args.force,
        mesh=None if args.per_tile else args.output,
    )  # fmt: skip
    if args.preview is not None:  # a missing extra stops the run here, not after it
        from .viz import picture_modules

        picture_modules()
    if args.inspect is not None:
        from .inspect._pictures import picture_modules

        picture_modules()
    if args.register and len(args.input) < 2:
        raise InputError(f"{args.input[0]}: --register needs two or more scans")
    config = ReconstructionConfig().with_overrides(**_config_overrides(args))
    if args.tiles is not None:
        return _run_tiled(args, config)
    if args.scheduler is not None or args.workers is not None or args.allow_gaps:
        raise InputError("--scheduler, --workers and --allow-gaps go with --tiles")
    several = len(args.input) > 1 or args.poses is not None
    reduce = {}
    if not (args.optimize or several):  # phase 2 takes every point the crop keeps
        reduce = dict(crop=config.crop, sample=config.sample, voxel_size=config.voxel_size)
        config = replace(config, crop=None, sample=None, voxel_size=None)
    start = time.perf_counter()
    clouds = [io.read_points(path, **reduce, seed=config.seed) for path in args.input]
    reading = {"seconds": time.perf_counter() - start, **clouds[0].reduction}
    cloud, registration = clouds[0], None
    if several:
        cloud, registration = _merge(args, clouds, config)
        config = replace(config, viewpoint=None)  # now in every point's sensor position
    simplify = not args.optimize and config.tolerance != 0.0
    with late_kernels_ahead(optimize=args.optimize, simplify=simplify):  # on a fresh install
        result = reconstruct(
            cloud.points,
            config,
            viewpoints=cloud.viewpoints,
            optimize=args.optimize,
            progress=not args.quiet,
        )
    finish = dict(
        points=cloud.points,
        source=", ".join(map(str, args.input)),
        mesh_path=args.output,
        report_paths=[args.report] if args.report else [],
        preview_path=args.preview,
        reading=reading,
        registration=registration,
        title=", ".join(path.name for path in args.input),
    )
    report = _finish(result, args, **finish)  # before the inspection, which may not run
    if args.inspect is None:
        return 0
    # The inspection measures the dense mesh, as fine as the surface's curvature needs,
    # unless phase 2 made the mesh.
    measured = result.mesh if args.optimize else result.dense_mesh
    sensors = config.viewpoint if cloud.viewpoints is None else cloud.viewpoints
    inspection = _inspect(args, measured, cloud.points, sensors, written=args.output)
    html = [path for path in finish["report_paths"] if path.suffix.lower() in HTML_SUFFIXES]
    _write_reports(
        html, result, report, points=cloud.points, source=finish["source"], inspection=inspection
    )  # the HTML report again, with the inspection in it
    _write_inspection(args, args.inspect, measured, cloud.points, *inspection)
    return 0


def _run_tiled(args: argparse.Namespace, config) -> int:
    """`reconstruct --tiles`: the tiles run on a Dask cluster, local unless --scheduler."""
    from . import io
    from .errors import InputError
    from .tiles import dask_client, parse_tiles, reconstruct_tiled

    if len(args.input) > 1 or args.poses or args.register or args.optimize or args.inspect:
        raise InputError(
            "--tiles takes one input, without --poses, --register, --optimize or --inspect"
        )
    if args.report is not None and args.report.suffix.lower() in HTML_SUFFIXES:
        raise InputError(
            f"{args.report}: with --tiles the points and planes stay on the workers; "
            "write the report as .json"
        )
    if args.workers is not None and (args.workers < 1 or args.scheduler is not None):
        raise InputError("--workers must be a positive count, for the local cluster only")
    source = io.check_input(args.input[0]).resolve()
    parse_tiles(args.tiles)
    with dask_client(args.scheduler, args.workers) as client:
        result = reconstruct_tiled(
            source,
            config,
            tiles=args.tiles,
            client=client,
            progress=not args.quiet,
            allow_gaps=args.allow_gaps,
        )
    _finish(
        result,
        args,
        points=None,
        source=str(args.input[0]),
        mesh_path=args.output,
        report_paths=[args.report] if args.report else [],
        preview_path=args.preview,
    )
    return 0


def _merge(args: argparse.Namespace, clouds: list, config) -> tuple:
    """One cloud of the scans moved by their poses (read, and refined with --register), and
    the registration's report (None without --register)."""
    import time

    import numpy as np

    from . import io
    from .merge import match_poses, merge_scans

    poses = None
    if args.poses is not None:
        names, matrices = io.read_poses(args.poses)
        poses = match_poses(args.input, names, matrices, source=str(args.poses))
    registration = None
    if args.register:
        from .registration import register_scans
        from .report import registration_report

        start = time.perf_counter()
        names = [path.name for path in args.input]
        refined = register_scans(
            [cloud.points for cloud in clouds],
            np.tile(np.eye(4), (len(clouds), 1, 1)) if poses is None else poses,
            names=names,
            progress=not args.quiet,
        )
        poses = refined.poses
        registration = registration_report(refined, names, time.perf_counter() - start)
    return merge_scans(clouds, poses, viewpoint=config.viewpoint), registration


def _run_optimize(args: argparse.Namespace) -> int:
    from . import io
    from .optimization import optimize_mesh
    from .report import optimization_lines, optimization_report

    _check_outputs(
        [args.output, args.report], [args.mesh, args.points], force=args.force, mesh=args.output
    )
    mesh = io.read_mesh(args.mesh)
    cloud = io.read_points(args.points)
    result = optimize_mesh(
        mesh, cloud.points, c_rep=args.c_rep, kappa=args.kappa, tolerance=args.tolerance,
        rng=args.seed, progress=not args.quiet,
    )  # fmt: skip
    io.write_mesh(args.output, result.mesh, binary=not args.ascii)
    report = optimization_report(result)
    report["files"] = {"mesh": str(args.mesh), "points": str(args.points)}
    if args.report is not None:
        io.write_json(args.report, report)
    if not args.quiet:
        print("\n".join(optimization_lines(report)))
        print(
            "seconds     "
            + ", ".join(f"{name} {sec:.2f}" for name, sec in report["timings"].items())
        )
        print(f"mesh        written to {args.output}")
    return 0


def _check_tile_folder(args: argparse.Namespace) -> None:
    """Refuse, before any work, a --per-tile output folder that cannot take the tiles."""
    from .errors import InputError
    from .tile_output import MANIFEST, check_folder

    if args.tiles is None:
        raise InputError("--per-tile goes with --tiles")
    folder = check_folder(args.output)
    if (folder / MANIFEST).exists() and not args.force:
        raise InputError(f"{folder}: holds a tiled mesh ({MANIFEST}); add --force to replace it")


def _check_outputs(
    outputs: list[Path | None], inputs: list[Path | None], *, force: bool, mesh: Path | None = None
) -> None:
    """Refuse, before any work, outputs that cannot be written or would lose data.

    An output must be writable (`io.check_output`), may not be an input (not even with
    --force) or named twice, nor an existing file unless `force`; `mesh` must have a mesh
    suffix.
    """
    import os

    from . import io
    from .errors import InputError

    if mesh is not None:
        io.check_output(mesh, mesh=True)
    written: list[Path] = []
    for target in filter(None, outputs):
        resolved = io.check_output(target).resolve()
        for source in filter(None, inputs):
            if resolved == source.resolve() or (
                resolved.exists() and source.exists() and os.path.samefile(resolved, source)
            ):
                raise InputError(f"{target}: is the input file {source}; write elsewhere")
        if resolved in written:
            raise InputError(f"{target}: named for two outputs")
        written.append(resolved)
        if resolved.exists() and not force:
            raise InputError(f"{target}: exists; add --force to replace it")


def _run_render(args: argparse.Namespace) -> int:
    import numpy as np

    from . import io
    from .errors import InputError
    from .viz import distance_colours, intensity_colours, preview, vertex_distances

    if args.output.suffix.lower() != ".png":
        raise InputError(f"{args.output}: the picture must be a .png file")
    _check_outputs([args.output], [args.mesh, args.points], force=args.force)
    try:
        width, height = (int(part) for part in args.size.lower().split("x"))
    except ValueError:
        raise InputError(f"--size must be WIDTHxHEIGHT, e.g. 1200x600; got {args.size!r}") from None
    if not (16 <= width <= 8192 and 16 <= height <= 8192):
        raise InputError(f"--size must be between 16 and 8192 pixels each way; got {args.size}")
    mesh = io.read_mesh(args.mesh)
    cloud = io.read_points(args.points) if args.points else None
    if cloud is None and (args.distance or args.normals or args.hide_points or args.intensity):
        raise InputError("--distance, --normals, --intensity and --hide-points need a POINTS file")
    if args.normals and cloud.normals is None:
        raise InputError(f"{args.points}: the file carries no normals to draw")
    if args.intensity and cloud.intensity is None:
        raise InputError(f"{args.points}: the file carries no intensity to colour by")
    title, colours = args.mesh.name, None
    if args.distance:
        distances = vertex_distances(mesh, cloud.points)
        limit = float(np.nanpercentile(distances, 95))
        colours = distance_colours(distances, limit=limit)
        title += f": colour = distance of the points, 0 (dark blue) to {limit:.3g} (yellow)"
    preview(
        mesh,
        args.output,
        title=title,
        points=None if cloud is None or args.hide_points else cloud.points,
        point_colours=intensity_colours(cloud.intensity) if args.intensity else None,
        normals=(cloud.points, cloud.normals) if args.normals else None,
        boundaries=not args.no_boundaries,
        colours=colours,
        width=width,
        height=height,
    )
    if not args.quiet:
        print(f"picture     written to {args.output}")
    return 0


#: The files an inspection writes to its folder.
INSPECTION_FILES = (
    "defects.csv",
    "joints.csv",
    "ovality.csv",
    "inspection.json",
    "deviation-map.png",
    "ovality.png",
    "deviation.png",
    "report.html",
)


def _inspection_files(folder: Path | None, more=()) -> list[Path]:
    """The files an inspection writes to `folder` (and the files named `more`), to check
    before any work: none without a folder, or when the folder is still to be made (in a
    folder that exists)."""
    from .errors import InputError

    if folder is None:
        return []
    if folder.exists() and not folder.is_dir():
        raise InputError(f"{folder}: is a file; the inspection writes a folder")
    if not folder.exists():
        if not folder.absolute().parent.is_dir():
            raise InputError(f"{folder}: cannot be made; folder {folder.parent} does not exist")
        return []
    return [folder / name for name in (*INSPECTION_FILES, *more)]


def _inspect(args: argparse.Namespace, mesh, points, viewpoints=None, *, written=None) -> tuple:
    """Inspect `mesh` as a pipe with the command's inspection options, and the scan's
    `points` and `viewpoints` when known; return the Inspection and its pictures
    ({caption: PNG bytes}). An `InspectionError` names the mesh file `written` before, if
    any, which it leaves as it is."""
    from .errors import InspectionError
    from .inspect import UP, deviation_map, inspect_pipe, mesh_picture, ovality_plot
    from .viz import RenderError

    try:
        inspection = inspect_pipe(
            mesh,
            points,
            viewpoints=viewpoints,
            nominal_diameter=args.nominal_diameter,
            threshold=None if args.threshold_mm is None else args.threshold_mm / 1000.0,
            up=UP if args.up is None else args.up,
        )
    except InspectionError as error:
        source = getattr(args, "mesh", None) or ", ".join(map(str, args.input))
        kept = "" if written is None else f" (the mesh is written to {written})"
        raise InspectionError(f"{source}: not inspected as a pipe{kept}: {error}") from error
    pictures = {
        "deviation-map.png": deviation_map(inspection),
        "ovality.png": ovality_plot(inspection),
    }
    try:
        pictures["deviation.png"] = mesh_picture(mesh, inspection)
    except RenderError as error:
        print(f"zeroset: no picture of the mesh: {error}", file=sys.stderr)
    return inspection, pictures


def _write_inspection(args, folder: Path, mesh, points, inspection, pictures) -> None:
    """Write an inspection's tables, numbers, pictures and HTML report to `folder`."""
    from . import io
    from .htmlreport import write_inspection_report
    from .inspect import (
        inspection_lines,
        inspection_summary,
        write_defects_csv,
        write_joints_csv,
        write_ovality_csv,
    )

    folder.mkdir(exist_ok=True)
    write_defects_csv(folder / "defects.csv", inspection)
    write_joints_csv(folder / "joints.csv", inspection)
    write_ovality_csv(folder / "ovality.csv", inspection)
    io.write_json(folder / "inspection.json", inspection_summary(inspection))
    for name, picture in pictures.items():
        with io.atomic_target(io.check_output(folder / name)) as temporary:
            temporary.write_bytes(picture)
    write_inspection_report(
        folder / "report.html",
        mesh,
        inspection,
        points=points,
        pictures=_captioned(pictures),
        source=str(getattr(args, "mesh", None) or ", ".join(map(str, args.input))),
    )
    if not args.quiet:
        print("\n".join(inspection_lines(inspection)))
        print(f"inspection  written to {folder}/: " + ", ".join(
            name for name in INSPECTION_FILES if name in pictures or not name.endswith(".png")
        ))  # fmt: skip


def _captioned(pictures: dict) -> dict:
    """The pictures keyed by their captions in the HTML report."""
    captions = {
        "deviation-map.png": "the unrolled wall, coloured by deviation",
        "ovality.png": "ovality along the pipe",
        "deviation.png": "the mesh, coloured by deviation",
    }
    return {captions[name]: picture for name, picture in pictures.items()}


def _run_inspect(args: argparse.Namespace) -> int:
    from . import io
    from .inspect._pictures import picture_modules

    picture_modules()  # a missing extra stops the run here, not after it
    _check_outputs(_inspection_files(args.output), [args.mesh, args.points], force=args.force)
    mesh = io.read_mesh(args.mesh)
    cloud = io.read_points(args.points) if args.points else None
    points = None if cloud is None else cloud.points
    inspection = _inspect(args, mesh, points, None if cloud is None else cloud.viewpoints)
    _write_inspection(args, args.output, mesh, points, *inspection)
    return 0


def _run_demo(args: argparse.Namespace) -> int:
    from . import io
    from ._kernels._ahead import late_kernels_ahead
    from .evaluate import sample_surface
    from .pipeline import reconstruct
    from .synthetic import sample_cylinder

    args.out.mkdir(parents=True, exist_ok=True)  # the demo replaces its own files there
    sample = sample_cylinder(args.points, radius=0.25, length=1.0, noise=0.002, rng=args.seed)
    points_path = io.write_points(args.out / "pipe-points.ply", sample.points)
    with late_kernels_ahead(simplify=True):  # on a fresh install
        result = reconstruct(sample.points, progress=not args.quiet, seed=args.seed)
        _finish(
            result,
            args,
            points=sample.points,
            source=str(points_path),
            mesh_path=args.out / "mesh.ply",
            report_paths=[args.out / "report.json", args.out / "report.html"],
            preview_path=args.out / "preview.png",
        )
    # Over the mesh's area: its vertices crowd at the open ends, where the boundary keeps
    # the dense mesh's.
    distance = sample.distance(sample_surface(result.mesh, DEMO_SAMPLES, rng=args.seed)[0])
    if not args.quiet:
        print(
            f"accuracy    the mesh lies {1000 * distance.mean():.2f} mm (mean over its area) "
            f"and {1000 * distance.max():.2f} mm (max) from the true pipe"
        )
        names = ("pipe-points.ply", "mesh.ply", "preview.png", "report.json", "report.html")
        written = ", ".join(name for name in names if (args.out / name).exists())
        print(f"wrote       {args.out}/: {written} (open report.html in a browser)")
    return 0


def _run_synth(args: argparse.Namespace) -> int:
    from . import synthetic
    from .errors import InputError

    def parse_numbers(option: str, text: str, form: str, counts=None) -> list[float]:
        """The comma-separated numbers given to `option`: one of `counts` of them, or any."""
        try:
            values = [float(part) for part in text.split(",")]
        except ValueError:
            values = []
        if not values or (counts is not None and len(values) not in counts):
            raise InputError(f"{option} must be {form}; got {text!r}")
        return values

    damaged = args.kind.startswith("damaged-")
    scan = args.kind.endswith("-scan")
    run = args.kind == "pipe-run"
    if (args.kind == "inject") != (args.scan is not None):
        raise InputError("a scan goes with inject, and inject needs one: zeroset synth inject SCAN")
    if args.kind != "inject" and (args.joint or args.mesh or args.up):
        raise InputError("--joint, --mesh and --up go with inject")
    if not (damaged or args.kind == "inject") and (args.dent or args.bulge):
        raise InputError("--dent and --bulge go with the damaged-* kinds and inject")
    if not (damaged or run) and args.ovality is not None:
        raise InputError("--ovality goes with the damaged-* kinds and pipe-run")
    for name in ("bends", "out_of_plane", "tee", "defects", "joints", "uniform"):
        if not run and getattr(args, name) not in (None, False, 0):
            raise InputError(f"--{name.replace('_', '-')} goes with pipe-run")
    if args.stations is not None and not (damaged and scan):
        raise InputError("--stations goes with damaged-pipe-scan and damaged-elbow-scan")
    with_length = ("cylinder", "tee", "pipe-scan", "damaged-pipe", "damaged-pipe-scan")
    if args.length is not None and args.kind not in with_length:
        raise InputError(f"--length does not apply to {args.kind}")
    defects = []
    for kind in ("dent", "bulge"):
        for text in getattr(args, kind):
            form = "AXIAL,CLOCK,DEPTH,WIDTH (metres, degrees, metres, metres)"
            axial, clock, depth, width = parse_numbers(f"--{kind}", text, form, (4,))
            try:
                defects.append(synthetic.Defect(kind, axial, clock, depth, width))
            except InputError as error:
                raise InputError(f"--{kind} {text}: {error}") from None
    if args.kind == "inject":
        joints = []
        for text in args.joint:
            kind, _, rest = text.partition(",")
            form = "KIND,AXIAL,SIZE[,CLOCK[,DEPTH]] (a kind, then metres, degrees, metres)"
            values = parse_numbers("--joint", rest, form, (2, 3, 4))
            try:
                joints.append(synthetic.Joint(kind, *values))
            except InputError as error:
                raise InputError(f"--joint {text}: {error}") from None
        return _inject(args, defects, joints)
    generator = getattr(synthetic, SYNTH_KINDS[args.kind])
    options = {"rng": args.seed, "outliers": args.outliers}
    if args.radius is not None:
        options["radius"] = args.radius
    if args.length is not None:
        options["length"] = args.length
    if damaged:
        options["defects"] = defects
        if args.ovality is not None:
            ovality = parse_numbers("--ovality", args.ovality, "VALUE or VALUE,CLOCK", (1, 2))
            options["ovality"] = ovality[0]
            options["ovality_clock"] = ovality[1] if len(ovality) == 2 else 0.0
        if args.stations is not None:
            options["stations"] = parse_numbers("--stations", args.stations, "S0,S1,...")
        if args.kind in ("damaged-elbow", "damaged-elbow-scan"):
            options["shape"] = "elbow"
    truth = args.output.with_name(f"{args.output.stem}-truth.ply")
    record = args.output.with_name(f"{args.output.stem}-truth.json") if damaged or run else None
    _check_outputs([args.output, truth, record], [], force=args.force)
    if run:
        bends = parse_numbers("--bends", args.bends or "2,4", "MIN,MAX", (2,))
        ovality = parse_numbers("--ovality", args.ovality, "VALUE", (1,)) if args.ovality else [0]
        spec = generator(
            args.seed,
            diameter=2.0 * options.pop("radius", 0.2),
            bends=tuple(int(b) if b == int(b) else b for b in bends),
            out_of_plane=args.out_of_plane,
            tee=args.tee,
            defects=args.defects,
            joints=(1.0, 3.0) if args.joints else None,
            ovality=ovality[0],
        )
        if args.uniform is not None:
            sample = spec.sample(args.uniform, noise=args.noise, **options)
        else:
            sample = spec.scan(
                rotation_step=args.rotation_step, noise_scale=args.noise_scale, **options
            )
    elif scan:
        options.update(rotation_step=args.rotation_step, noise_scale=args.noise_scale)
        sample = generator(**options)
    else:
        if args.kind == "two-spheres":
            options.pop("radius", None)
        sample = generator(args.points, noise=args.noise, **options)
    points_path, truth_path = synthetic.write_sample(sample, args.output)
    if not args.quiet:
        print(
            f"wrote {sample.points.shape[0]:,} points to {points_path}"
            + (f", the true surface to {truth_path}" if truth_path else "")
            + (f" and the truth record to {record}" if record else "")
        )
    return 0


def _inject(args: argparse.Namespace, defects: list, joints: list) -> int:
    """``zeroset synth inject``: `defects` and `joints` put into the points of ``args.scan``,
    written with their truth."""
    from . import io
    from .inspect import UP, fit_pipe
    from .pipeline import reconstruct
    from .synthetic import inject

    record = args.output.with_name(f"{args.output.stem}-truth.json")
    _check_outputs([args.output, record], [args.scan, args.mesh], force=args.force)
    cloud = io.read_points(args.scan)
    if args.mesh is not None:
        mesh = io.read_mesh(args.mesh)
    else:
        mesh = reconstruct(  # the dense mesh, as the inspection fits it; no few triangles
            cloud.points, viewpoints=cloud.viewpoints, tolerance=0.0, progress=not args.quiet
        ).dense_mesh
    pipe = fit_pipe(mesh, cloud.points, viewpoints=cloud.viewpoints, up=args.up or UP)
    moved, truth = inject(
        cloud.points, pipe, defects=defects, joints=joints, viewpoints=cloud.viewpoints
    )
    io.write_points(args.output, moved, viewpoints=cloud.viewpoints)
    io.write_json(record, {"source": str(args.scan), **truth})
    if not args.quiet:
        print(
            f"moved {truth['moved']:,} of {moved.shape[0]:,} points for {len(defects)} "
            f"defect(s) and {len(joints)} joint(s) on the pipe fitted to {args.scan} "
            f"({pipe.length:.2f} m, diameter {2000 * pipe.radius:.1f} mm); wrote {args.output} "
            f"and the truth to {record}"
        )
    return 0


def _run_evaluate(args: argparse.Namespace) -> int:
    from . import io
    from .evaluate import evaluate, format_report

    _check_outputs([args.json], [args.mesh, args.reference, args.scan], force=args.force)
    mesh = io.read_mesh(args.mesh)
    reference = io.read_mesh(args.reference) if args.reference else None
    points = io.read_points(args.scan).points if args.scan else None
    taus = tuple(args.tau) if args.tau else (0.01, 0.005)
    report = evaluate(
        mesh, reference=reference, points=points, n_samples=args.samples, taus=taus, rng=args.seed
    )
    report["files"] = {
        "mesh": str(args.mesh),
        "reference": args.reference and str(args.reference),
        "points": args.scan and str(args.scan),
    }
    if args.json is not None:
        io.write_json(args.json, report)
    if not args.quiet:
        print(format_report(report))
    return 0


def _finish(
    result,
    args,
    *,
    points,
    source,
    mesh_path,
    report_paths,
    preview_path,
    reading=None,
    registration=None,
    title=None,
) -> dict:
    """Write the mesh, reports (JSON or HTML, by suffix) and preview; print the summary;
    return the report (see `zeroset.report.reconstruction_report`)."""
    from . import io
    from ._progress import peak_mib
    from .report import format_report, reconstruction_report

    binary = not getattr(args, "ascii", False)
    if getattr(args, "per_tile", False):
        from .tile_output import MANIFEST, write_tile_meshes

        write_tile_meshes(mesh_path, result.mesh, result.tiles, result.offset,
                          result.parameters.cube_size, binary=binary)  # fmt: skip
        written = f"{mesh_path}, one file a tile, and {MANIFEST}"
    else:
        io.write_mesh(mesh_path, result.mesh, binary=binary)
        written = mesh_path
    report = reconstruction_report(
        result, source=source, points=points, reading=reading, registration=registration
    )
    if (peak := peak_mib()) is not None:
        report["peak_mib"] = peak
    _write_reports(report_paths, result, report, points=points, source=source)
    if preview_path is not None:
        from .errors import MissingExtraError
        from .viz import RenderError, preview

        try:
            preview(result.mesh, preview_path, title=title or Path(source).name)
        except (RenderError, MissingExtraError) as error:
            if args.command != "demo":
                raise
            print(f"zeroset: no preview picture: {error}", file=sys.stderr)
    if not args.quiet:
        print(format_report(report))
        print(f"mesh        written to {written}")
    return report


def _write_reports(paths, result, report: dict, *, points, source, inspection=None) -> None:
    """Write `report` to each of `paths`: JSON, or HTML by suffix, which shows the points,
    the meshes and `inspection`, an (Inspection, pictures) pair from `_inspect`."""
    from . import io
    from .htmlreport import write_html_report

    for path in paths:
        if path.suffix.lower() in HTML_SUFFIXES:
            write_html_report(
                path,
                result,
                points=points,
                source=source,
                report=report,
                **({} if inspection is None else dict(
                    inspection=inspection[0], pictures=_captioned(inspection[1])
                )),
            )  # fmt: skip
        else:
            io.write_json(path, report)
