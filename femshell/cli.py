"""The ``femshell`` command line: ``mesh``, ``validate``, ``run``, ``sweep``, ``scenes``, ``render``,
``warmup``; exit code 0 done, 1 failed, 2 bad input (one clear line per problem, no traceback),
130 interrupted."""

from __future__ import annotations

import argparse
import contextlib
import difflib
import os
import signal
import sys
import time
import warnings
from pathlib import Path

from .config import configure

MESH_KINDS = ("sphere", "disk", "plate", "strip", "annulus", "cylinder", "hemisphere")
#: the kinds each geometric option of `femshell mesh` applies to
MESH_OPTIONS = {"radius": ("sphere", "disk", "cylinder", "hemisphere"), "inner_radius": ("disk", "annulus"),
                "outer_radius": ("annulus",), "vertices": ("sphere", "disk", "hemisphere"),
                "edge_length": MESH_KINDS, "inner_edge_length": ("disk",), "length": ("plate", "strip", "cylinder"),
                "width": ("plate", "strip"), "angle": ("cylinder",), "hole_angle": ("hemisphere",),
                "slit": ("annulus",), "refine_inside": ("disk",)}


def _positive(name):
    def parse(text):
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{name} must be a number, got '{text}'")
        if not v > 0:
            raise argparse.ArgumentTypeError(f"{name} must be > 0, got {text}")
        return v
    return parse


def _mesh_parser(sub):
    m = sub.add_parser("mesh", help="generate a mesh with gmsh and write it (.vtu, .msh, .xdmf)",
                       description="Generate a mesh and write it; prints its size, topology and quality.")
    m.add_argument("kind", choices=MESH_KINDS)
    m.add_argument("-o", "--output", required=True, help="output file (.vtu, .msh or .xdmf)")
    m.add_argument("--overwrite", action="store_true", help="replace the output file if it exists")
    m.add_argument("--radius", type=_positive("--radius"), help="sphere/disk/cylinder/hemisphere radius")
    m.add_argument("--inner-radius", type=_positive("--inner-radius"),
                   help="disk: conforming inner circle radius R2; annulus: inner radius")
    m.add_argument("--outer-radius", type=_positive("--outer-radius"), help="annulus outer radius")
    m.add_argument("--vertices", type=int, help="target number of vertices (sphere, disk, hemisphere)")
    m.add_argument("--edge-length", type=_positive("--edge-length"), help="target edge length")
    m.add_argument("--inner-edge-length", type=_positive("--inner-edge-length"),
                   help="disk: edge length near the inner circle")
    m.add_argument("--length", type=_positive("--length"), help="plate/strip x length, cylinder length")
    m.add_argument("--width", type=_positive("--width"), help="plate/strip y width")
    m.add_argument("--angle", type=float, nargs=2, metavar=("THETA0", "THETA1"),
                   help="cylinder: panel angle range in degrees")
    m.add_argument("--hole-angle", type=float, help="hemisphere: polar hole half-angle in degrees")
    m.add_argument("--slit", action="store_true", help="annulus: cut along the positive x-axis")
    m.add_argument("--refine-inside", action="store_true",
                   help="disk: the inner edge length over the whole inner disk, not only near the circle")
    m.add_argument("--seed", type=int, default=0)


def _run_parser(sub):
    r = sub.add_parser(
        "run", help="run a scene (TOML file or embedded scene name)",
        description="Run a scene; writes into --out a ParaView time series (series.pvd + VTU frames), "
                    "summary.json, pictures/, scene.toml (the scene as run) and checkpoint.npz.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
               "  femshell run default                         the README's scene, into ./default-out\n"
               "  femshell run my.toml --out runs/a --dry-run  show what would be built, compute nothing\n"
               "  femshell run sphere-spots --set mesh.n_vertices=2000 --set solver.t_final=5\n"
               "  femshell run sphere-spots --out runs/b --resume   continue after Ctrl-C or a kill\n\n"
               "--set KEY=VALUE overrides one scene key (section.key; VALUE is TOML, or a bare word taken as a\n"
               "string; boundary.0.curve=left reaches into lists; a table merges: material={E=2} is\n"
               "material.E=2, the section's other keys kept). Setting mesh.n_vertices drops the file's\n"
               "mesh.edge_length and vice versa. The run's description (header, summary.json, scene.toml)\n"
               "ends with the overrides, [--set ...]. `femshell scenes NAME` prints an embedded scene to start from.\n\n"
               "An --out that holds a run is never overwritten silently: give --resume (continue it) or\n"
               "--overwrite (replace femshell's files there; the earlier run is put back if the new one\n"
               "cannot start). Ctrl-C stops after a checkpoint.\n\n"
               "By default the factorisations and element kernels use every core, and a resumed run\n"
               "continues the uninterrupted one to round-off; --reproducible (give it to the run and to\n"
               "every --resume) makes resumes repeat the uninterrupted run bit for bit, on one core.\n"
               "exit codes: 0 done (or paused by --max-steps), 1 a step failed, 2 bad input, 130 interrupted")
    r.add_argument("scene", nargs="?", help="a .toml file or the name of an embedded scene (see `femshell scenes`); "
                                            "may be left out with --resume (the scene in --out is used)")
    r.add_argument("--out", help="output directory (default: ./NAME-out)")
    r.add_argument("--resume", action="store_true", help="continue from the last checkpoint in --out")
    r.add_argument("--overwrite", action="store_true", help="replace a run that --out already holds")
    r.add_argument("--dry-run", action="store_true", help="print what the scene will build, compute nothing")
    r.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scene key, e.g. --set mesh.n_vertices=500 (repeatable)")
    r.add_argument("--max-steps", type=int, metavar="N",
                   help="stop after N steps in this invocation (checkpointed; continue with --resume)")
    r.add_argument("--reproducible", action="store_true",
                   help="bit-for-bit repeatable results, a resume included: MKL's strict reproducibility mode "
                        "(sequential layer) and one thread for MKL and the element kernels (slower on large meshes)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    r.add_argument("-v", "--verbose", action="store_true", help="also print step cuts and solver details")


def _sweep_parser(sub):
    w = sub.add_parser(
        "sweep", help="run a scene over a grid or list of parameter values on Dask (local or a cluster)",
        description="Run every point of a sweep spec (a base scene and scene keys varied over it) as an ordinary\n"
                    "run directory DIR/points/<key>/, on a Dask LocalCluster (one single-threaded worker process\n"
                    "per CPU) or an existing Dask cluster; writes DIR/manifest.json, DIR/results.csv (+ .parquet\n"
                    "with pyarrow), DIR/phase_diagram.png and DIR/contact_sheet.png (docs/guide/sweeps.md).",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="spec (TOML):\n"
               '  scene = "default"                      embedded scene name or .toml path (relative to the spec)\n'
               '  mode = "product"                       or "zip" (the i-th values of every axis together)\n'
               '  measures = ["regime", "n_spots"]       table columns (default: all)\n'
               '  [set]   "solver.t_final" = 20          scene keys set at every point\n'
               '  [vary]  "growth.c_star" = [0.05, 0.1]  the axes: dotted scene keys and their values\n'
               '  [plot]  x = "growth.c_star"            phase diagram axes (default: the first two of [vary])\n\n'
               "examples:\n"
               "  femshell sweep grid.toml --out runs/grid                 local cluster, one worker per CPU\n"
               "  femshell sweep grid.toml --out runs/grid --resume        continue after Ctrl-C or a kill\n"
               "  femshell sweep grid.toml --scheduler tcp://host:8786     workers: dask worker --nthreads 1\n"
               "  femshell sweep --plot runs/grid                          table and pictures again\n\n"
               "The spec and every point's scene are validated before anything starts. A point that fails is\n"
               "recorded and the others go on; a worker killed mid-point is replaced and the point resumes from\n"
               "its checkpoint. Ctrl-C stops every point at its next step (checkpointed); --resume continues.\n"
               "exit codes: 0 every point finished, 1 some failed, 2 bad input, 130 interrupted")
    w.add_argument("spec", nargs="?", help="the sweep spec (.toml)")
    w.add_argument("--out", help="output directory (default: ./SPECNAME-sweep)")
    w.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler, e.g. tcp://host:8786")
    w.add_argument("--workers", type=int, metavar="N", help="local cluster: N worker processes (default: one per "
                                                                "CPU, at most one per point)")
    w.add_argument("--resume", action="store_true", help="continue the sweep in --out (finished points are skipped)")
    w.add_argument("--retry-failed", action="store_true", help="with --resume: run the failed points again too")
    w.add_argument("--plot", metavar="DIR", help="only write DIR's results table and pictures again")
    w.add_argument("--no-plot", action="store_true", help="no phase diagram or contact sheet at the end")


def _parser():
    p = argparse.ArgumentParser(
        prog="femshell",
        description="Finite-element thin shells that grow, buckle and wrinkle under a chemical signal "
                    "(Zakharov & Dasbiswas model). Subcommands:\n"
                    "  mesh      generate a mesh (sphere, disk, plate, strip, annulus, cylinder, hemisphere)\n"
                    "  validate  run a validation case against theory or a benchmark\n"
                    "  run       run a scene (a .toml file or an embedded scene name)\n"
                    "  sweep     run a scene over a grid of parameter values on Dask\n"
                    "  scenes    list the embedded scenes\n"
                    "  render    pictures and a movie of a finished run\n"
                    "  warmup    compile the element kernels once, ahead of the first run\n"
                    "  stationary  Newton on the stationary coupled system from a time run (--from DIR)",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    _mesh_parser(sub)

    v = sub.add_parser("validate", help="run validation cases; exit 0 only if every toleranced row passes",
                       description="Compare femshell with theory and benchmarks; writes OUT/NAME.json and NAME.png.")
    v.add_argument("name", nargs="*", help="case names (see --list); 'all' runs every case")
    v.add_argument("--list", action="store_true", help="list the validation cases")
    v.add_argument("--level", choices=("quick", "full"), default="quick")
    v.add_argument("--out", default="validation-out", help="output directory (default: validation-out)")

    _run_parser(sub)
    _sweep_parser(sub)

    sc = sub.add_parser("scenes", help="list the embedded scenes, one line each; `scenes NAME` prints one",
                        description="List the embedded scenes; with a NAME, print that scene's TOML file "
                                    "(a starting point for your own: femshell scenes default > my.toml).")
    sc.add_argument("name", nargs="?", help="print this embedded scene")

    d = sub.add_parser("render", help="pictures and a movie of a finished run directory",
                       description="Render DIR's time series: a top view per frame (pictures/top_NNNNNN.png, one "
                                   "colour range for all frames), a side view of the last frame "
                                   "(pictures/side_last.png) and DIR/movie.gif.")
    d.add_argument("dir", help="a run directory (written by femshell run)")
    d.add_argument("--field", help="field to colour by (default c, else the first scalar field)")
    d.add_argument("--series", help="the time series NAME.pvd to render (default series.pvd, else the only one)")
    d.add_argument("--every", type=int, default=1, help="render every N-th frame (the last one always)")
    d.add_argument("--fps", type=_positive("--fps"), default=5.0, help="movie frames per second (at most 50 for a GIF)")
    d.add_argument("--cmap", default="viridis", help="matplotlib colour map")
    d.add_argument("--no-movie", action="store_true", help="pictures only")
    sub.add_parser("warmup", help="compile the element kernels once (kept on disk for later runs)",
                   description="Compile the element kernels (C and JAX) into the user's cache directories, so "
                               "that no run pays for compiling them (about 20-60 s once).")
    st = sub.add_parser("stationary", help="the stationary state near a time run's last state (Newton on (x, c))",
                        description="Newton on the stationary coupled system (mechanical equilibrium and "
                                    "D Δc + P(H) − βc = 0 on the deformed surface; docs: theory §2.9) from the "
                                    "last checkpoint of the time run in DIR; writes DIR/stationary.json and "
                                    "DIR/stationary.vtu. Exit 0 when it converged, 1 when not.")
    st.add_argument("--from", dest="run_dir", required=True, metavar="DIR", help="a time run's --out directory")
    st.add_argument("--tol", type=_positive("--tol"), default=1e-9,
                    help="force (per unit-strain force) and rate of c (per β c_scale) to reach (default 1e-9)")
    st.add_argument("--max-iter", type=int, default=30, help="Newton steps at most (default 30)")
    p.subcommands = sub.choices      # name -> parser, for their usage errors
    return p


def _cmd_mesh(args):
    import math

    # each command imports what it uses when it runs: gmsh, jax, pyvista and matplotlib stay out of
    # `femshell --help` and of the other commands
    from .mesh import check_mesh, format_quality, generators, quality_report, write_mesh

    out = Path(args.output)
    if out.is_dir():
        raise ValueError(f"-o {out} is a directory: give a file name ending in .vtu, .msh or .xdmf")
    check_writable_dir(out.parent, "the output's directory")   # before meshing, not after
    existing = [f for f in (out, out.with_suffix(".h5") if out.suffix == ".xdmf" else None)
                if f is not None and f.exists()]
    if existing and not args.overwrite:   # checked before meshing: no output lost, no time wasted
        raise ValueError(f"{', '.join(map(str, existing))} exists; pass --overwrite to replace it")
    stray = [f"--{k.replace('_', '-')}" for k, kinds in MESH_OPTIONS.items()
             if args.kind not in kinds and getattr(args, k) not in (None, False)]
    if stray:       # an option the kind ignores would leave the user believing it was applied
        own = [f"--{k.replace('_', '-')}" for k, kinds in MESH_OPTIONS.items() if args.kind in kinds]
        raise ValueError(f"{', '.join(stray)} {'does' if len(stray) == 1 else 'do'} not apply to {args.kind} "
                         f"(its options: {', '.join(own)})")
    g = generators
    kw = {"seed": args.seed}
    if args.kind in ("sphere", "hemisphere"):
        kw.update(radius=args.radius or 1.0)
        if args.vertices is not None:
            kw["n_vertices"] = args.vertices
        if args.edge_length:
            kw["edge_length"] = args.edge_length
        if args.kind == "hemisphere" and args.hole_angle is not None:
            if not 0 < args.hole_angle < 90:
                raise ValueError(f"--hole-angle must be in (0, 90) degrees, got {args.hole_angle:g}")
            kw["hole_angle"] = math.radians(args.hole_angle)
    elif args.kind == "disk":
        kw.update(radius=args.radius or 1.0, edge_length=args.edge_length, n_vertices=args.vertices,
                  inner_radius=args.inner_radius, inner_edge_length=args.inner_edge_length,
                  refine_inside=args.refine_inside)
    elif args.kind in ("plate", "strip"):
        lx, ly = args.length or 1.0, args.width or (1.0 if args.kind == "plate" else 0.1)
        kw.update(edge_length=args.edge_length or min(lx, ly) / 10)
        kw.update(lx=lx, ly=ly) if args.kind == "plate" else kw.update(length=lx, width=ly)
    elif args.kind == "annulus":
        if not (args.inner_radius and args.outer_radius):
            raise ValueError("annulus: --inner-radius and --outer-radius are required")
        kw.update(inner_radius=args.inner_radius, outer_radius=args.outer_radius, slit=args.slit,
                  edge_length=args.edge_length or (args.outer_radius - args.inner_radius) / 8)
    elif args.kind == "cylinder":
        radius, length = args.radius or 1.0, args.length or 1.0
        kw.update(radius=radius, length=length, edge_length=args.edge_length or min(radius, length) / 8)
        if args.angle:
            a0, a1 = args.angle
            if not (math.isfinite(a0) and math.isfinite(a1) and 0 < a1 - a0 < 360):
                raise ValueError("--angle THETA0 THETA1 must have 0 < THETA1 - THETA0 < 360 degrees, "
                                 f"got {a0:g} {a1:g}")
            kw["angle_range"] = (math.radians(a0), math.radians(a1))
    t0 = time.perf_counter()
    try:
        mesh = getattr(g, args.kind)(**{k: v for k, v in kw.items() if v is not None})
    except RuntimeError as exc:     # gmsh could not mesh what the options describe
        raise ValueError(f"{args.kind}: {exc} (an extreme option value? see femshell mesh {args.kind} --help)") from None
    elapsed = time.perf_counter() - t0
    report = check_mesh(mesh)
    write_mesh(mesh, args.output)
    print(f"{mesh}\nmeshed in {elapsed:.2f} s; {report}")
    print(format_quality(quality_report(mesh)))
    print(f"wrote {args.output}")


def _cmd_validate(args):
    from .validation import list_cases, run_case      # deferred: jax (see _cmd_mesh)

    cases = list_cases()
    if "all" in args.name and len(args.name) > 1:
        raise ValueError("'all' runs every case; give it alone or name the cases")
    names = list(cases) if args.name in ([], ["all"]) else args.name
    unknown = [n for n in names if n not in cases]
    if unknown:
        raise ValueError(f"unknown validation case(s): {', '.join(unknown)}; available: {', '.join(cases)}")
    if args.list or not args.name:
        for name in names:
            print(f"{name:<34} {cases[name]}")
        return 0
    check_writable_dir(Path(args.out), "--out")   # before hours of computing, not after
    ok = True
    broken = []
    for name in names:
        earlier = Path(args.out) / f"{name}.json"
        before = earlier.stat().st_mtime_ns if earlier.exists() else None
        print(f"== {name} ({args.level})" + (f"; replaces {earlier}" if before else ""))
        try:
            ok &= run_case(name, args.level, args.out)
        except Exception as exc:      # a computation that fails is a failed case, not bad input: go on
            import traceback

            where = traceback.extract_tb(exc.__traceback__)[-1]
            now = earlier.stat().st_mtime_ns if earlier.exists() else None
            kept = ("" if now is None else f"; the earlier {earlier} is kept" if now == before
                    else f"; {earlier} was written before the error")
            print(f"{name}: FAILED: the case stopped with {type(exc).__name__}: {exc} "
                  f"(at {Path(where.filename).name}:{where.lineno}){kept}", file=sys.stderr)
            broken.append(name)
            ok = False
    print(f"results in {args.out}/")
    if broken:
        print(f"cases that stopped with an error: {', '.join(broken)}", file=sys.stderr)
    return 0 if ok else 1


def _cmd_run(args):
    from .scene import run_scene      # deferred: the solvers (see _cmd_mesh)

    if args.reproducible:             # before the first factorisation loads MKL
        configure(blas_threads=None, jax_cache_dir=None, reproducible=True)
    return run_scene(args.scene, out=args.out, resume=args.resume, dry_run=args.dry_run,
                     overwrite=args.overwrite, overrides=args.overrides, max_steps=args.max_steps,
                     quiet=args.quiet, verbose=args.verbose)


def _cmd_sweep(args):
    from .sweep import finish, load_spec, read_manifest, run_sweep      # deferred: the solvers

    if args.plot:
        if args.spec or args.resume or args.scheduler or args.workers or args.out:
            raise ValueError("--plot DIR redraws a sweep's table and pictures: give it alone")
        manifest = read_manifest(Path(args.plot))
        if manifest is None:
            raise ValueError(f"--plot {args.plot}: no sweep there (no manifest.json)")
        finish(Path(args.plot).resolve(), manifest, sys.stdout)
        return 0
    if not args.spec:
        raise ValueError("give a SPEC (a sweep's .toml file; see femshell sweep --help), or --plot DIR")
    if args.retry_failed and not args.resume:
        raise ValueError("--retry-failed applies to --resume")
    spec = load_spec(args.spec)
    return run_sweep(spec, args.out, scheduler=args.scheduler, workers=args.workers, resume=args.resume,
                     retry_failed=args.retry_failed, plot=not args.no_plot)


def _cmd_scenes(args):
    from .scene import embedded_scene_path, list_scenes

    scenes = list_scenes()
    if args.name:
        p = embedded_scene_path(args.name)
        if p is None:
            s = difflib.get_close_matches(args.name, list(scenes), n=1, cutoff=0.5)
            raise ValueError(f"no embedded scene '{args.name}'{f'; did you mean {s[0]!r}?' if s else ''} "
                             f"(embedded: {', '.join(scenes)})")
        sys.stdout.write(p.read_text(encoding="utf-8"))
        return 0
    for name, desc in scenes.items():
        print(f"{name:<28} {desc}")
    return 0


def check_writable_dir(path, what):
    from .io import check_writable_dir as check     # lazily: `femshell --help` stays quick

    return check(path, what)


def _cmd_render(args):
    from .viz import render_run       # deferred: pyvista, matplotlib

    if args.every < 1:
        raise ValueError(f"--every must be >= 1, got {args.every}")
    if Path(args.dir).is_dir():
        from .io import find_series
        from .scene.runner import pictures_pending, recover_run_dir, run_scene

        recover_run_dir(args.dir, busy_ok=True)      # an --overwrite killed while it started: its earlier run back
        if pictures_pending(args.dir):               # a finished run stopped before its final pictures
            code = run_scene(None, out=args.dir, resume=True, quiet=True)
            if code:
                return code

        find_series(Path(args.dir), args.series)     # a directory that is no run: said before pictures/ is made
        check_writable_dir(Path(args.dir) / "pictures", "pictures directory")
    t0 = time.perf_counter()
    paths = render_run(args.dir, field=args.field, series=args.series, every=args.every, movie=not args.no_movie,
                       fps=args.fps, cmap=args.cmap)
    tops = [p for p in paths if Path(p).name.startswith("top_")]
    others = [p for p in paths if not Path(p).name.startswith("top_")]
    print(f"rendered {len(tops)} top view(s) in {Path(args.dir) / 'pictures'}/ and {', '.join(map(str, others))} "
          f"in {time.perf_counter() - t0:.1f} s")
    return 0


def _cmd_warmup(args):
    from .config import default_jax_cache_dir, default_kernel_cache_dir
    from .shell.warmup import warm_up      # deferred: jax (see _cmd_mesh)

    print("compiling the element kernels (once: later runs load them from the cache)...", flush=True)
    for what, seconds in warm_up():
        print(f"  {what}: {seconds:.1f} s", flush=True)
    jax_dir = os.environ.get("JAX_COMPILATION_CACHE_DIR") or default_jax_cache_dir()
    print(f"kept in {jax_dir} (JAX) and {default_kernel_cache_dir()} (C)")
    return 0


def _cmd_stationary(args):
    from .scene.stationary_command import stationary_from_run      # deferred: the solvers

    if args.max_iter < 0:
        raise ValueError(f"--max-iter must be >= 0, got {args.max_iter}")
    return stationary_from_run(args.run_dir, tol=args.tol, max_iter=args.max_iter)


def main(argv=None):
    configure()          # process settings (BLAS threads, JAX cache): femshell.config
    parser = _parser()
    args, unknown = parser.parse_known_args(argv)
    if unknown:     # said with the subcommand's usage, not the top level's
        (parser.subcommands.get(args.command) or parser).error(f"unrecognized arguments: {' '.join(unknown)}")
    if args.command is None:
        parser.print_help()
        return 0
    handler = {"mesh": _cmd_mesh, "validate": _cmd_validate, "run": _cmd_run, "sweep": _cmd_sweep,
               "scenes": _cmd_scenes, "render": _cmd_render, "warmup": _cmd_warmup,
               "stationary": _cmd_stationary}[args.command]
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            return handler(args) or 0
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader closed the pipe (| head): stop quietly, as shell tools do
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except (ValueError, OSError) as exc:  # bad input or an unusable path: a clear message, no traceback
        if isinstance(exc, OSError) and exc.strerror:
            exc = f"cannot use {exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
        lines = str(exc).splitlines() or [type(exc).__name__]
        if type(exc).__name__ == "SceneError":      # one problem per line, each with the prefix
            for line in lines:
                print(f"femshell {args.command}: error: {line}", file=sys.stderr)
        else:
            print(f"femshell {args.command}: error: " + "\n".join(lines), file=sys.stderr)
        return 2


def _show_warning(message, category, filename, lineno, file=None, line=None):
    """A warning as one line, "warning: ...": not the file, line number and source line of where it
    was raised, which read like a fragment of a traceback."""
    print(f"warning: {message}", file=file or sys.stderr)


def console_main():
    """The ``femshell`` command: :func:`main`, then an exit that a further Ctrl-C cannot disturb.

    Once main returns, every output is written; a second Ctrl-C while Python shuts down (JAX's
    clean-up takes a moment) printed a traceback from an atexit callback or turned exit code 130
    into death by signal.
    """
    code = main()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(ValueError):       # not the main thread: nothing to ignore
            signal.signal(sig, signal.SIG_IGN)
    sys.exit(code)


if __name__ == "__main__":
    console_main()
