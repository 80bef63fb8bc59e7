"""The ``femshell`` command line (contract: design.md section 4)."""

from __future__ import annotations

import argparse
import sys
import time

MESH_KINDS = ("sphere", "disk", "plate", "strip", "annulus", "cylinder", "hemisphere")


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


def _parser():
    p = argparse.ArgumentParser(
        prog="femshell",
        description="Finite-element thin shells that grow, buckle and wrinkle under a chemical signal "
                    "(Zakharov & Dasbiswas model). Subcommands:\n"
                    "  mesh      generate a mesh (sphere, disk, plate, strip, annulus, cylinder, hemisphere)\n"
                    "  validate  run a validation case against theory or a benchmark\n"
                    "  run       run a scene (a .toml file or an embedded scene name)\n"
                    "  scenes    list the embedded scenes",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="command", metavar="COMMAND")

    m = sub.add_parser("mesh", help="generate a mesh with gmsh and write it (.vtu, .msh, .xdmf)",
                       description="Generate a mesh and write it; prints its size, topology and quality.")
    m.add_argument("kind", choices=MESH_KINDS)
    m.add_argument("-o", "--output", required=True, help="output file (.vtu, .msh or .xdmf)")
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
    m.add_argument("--seed", type=int, default=0)

    v = sub.add_parser("validate", help="run validation cases; exit 0 only if every toleranced row passes",
                       description="Compare femshell with theory and benchmarks; writes OUT/NAME.json and NAME.png.")
    v.add_argument("name", nargs="*", help="case names (see --list); 'all' runs every case")
    v.add_argument("--list", action="store_true", help="list the validation cases")
    v.add_argument("--level", choices=("quick", "full"), default="quick")
    v.add_argument("--out", default="validation-out", help="output directory (default: validation-out)")

    r = sub.add_parser("run", help="run a scene (TOML file or embedded scene name)",
                       description="Run a scene; writes a time series, summary.json and pictures into --out.")
    r.add_argument("scene", help="a .toml file or the name of an embedded scene (see `femshell scenes`)")
    r.add_argument("--out", help="output directory (default: ./NAME-out)")
    r.add_argument("--resume", action="store_true", help="continue from the last checkpoint in --out")
    r.add_argument("--dry-run", action="store_true", help="print what the scene will build, compute nothing")

    sub.add_parser("scenes", help="list the embedded scenes, one line each")
    return p


def _cmd_mesh(args):
    import math

    from .mesh import check_mesh, format_quality, generators, quality_report, write_mesh

    g = generators
    kw = {"seed": args.seed}
    if args.kind in ("sphere", "hemisphere"):
        kw.update(radius=args.radius or 1.0)
        if args.vertices:
            kw["n_vertices"] = args.vertices
        if args.edge_length:
            kw["edge_length"] = args.edge_length
        if args.kind == "hemisphere" and args.hole_angle is not None:
            kw["hole_angle"] = math.radians(args.hole_angle)
    elif args.kind == "disk":
        kw.update(radius=args.radius or 1.0, edge_length=args.edge_length, n_vertices=args.vertices,
                  inner_radius=args.inner_radius, inner_edge_length=args.inner_edge_length)
    elif args.kind in ("plate", "strip"):
        lx, ly = args.length or 1.0, args.width or (1.0 if args.kind == "plate" else 0.1)
        kw.update(edge_length=args.edge_length or min(lx, ly) / 10)
        kw.update(lx=lx, ly=ly) if args.kind == "plate" else kw.update(length=lx, width=ly)
    elif args.kind == "annulus":
        if not (args.inner_radius and args.outer_radius):
            raise SystemExit("femshell mesh annulus: --inner-radius and --outer-radius are required")
        kw.update(inner_radius=args.inner_radius, outer_radius=args.outer_radius, slit=args.slit,
                  edge_length=args.edge_length or (args.outer_radius - args.inner_radius) / 8)
    elif args.kind == "cylinder":
        radius, length = args.radius or 1.0, args.length or 1.0
        kw.update(radius=radius, length=length, edge_length=args.edge_length or min(radius, length) / 8)
        if args.angle:
            kw["angle_range"] = tuple(math.radians(a) for a in args.angle)
    t0 = time.perf_counter()
    mesh = getattr(g, args.kind)(**{k: v for k, v in kw.items() if v is not None})
    elapsed = time.perf_counter() - t0
    report = check_mesh(mesh)
    write_mesh(mesh, args.output)
    print(f"{mesh}\nmeshed in {elapsed:.2f} s; {report}")
    print(format_quality(quality_report(mesh)))
    print(f"wrote {args.output}")


def _cmd_validate(args):
    from .validation import list_cases, run_case

    cases = list_cases()
    if args.list or not args.name:
        for name, desc in cases.items():
            print(f"{name:<34} {desc}")
        return 0
    names = list(cases) if args.name == ["all"] else args.name
    unknown = [n for n in names if n not in cases]
    if unknown:
        raise SystemExit(f"unknown validation case(s): {', '.join(unknown)}; available: {', '.join(cases)}")
    ok = True
    for name in names:
        print(f"== {name} ({args.level})")
        ok &= run_case(name, args.level, args.out)
    print(f"results in {args.out}/")
    return 0 if ok else 1


def _cmd_run(args):
    from .scene import run_scene

    return run_scene(args.scene, out=args.out, resume=args.resume, dry_run=args.dry_run)


def _cmd_scenes(args):
    from .scene import list_scenes

    for name, desc in list_scenes().items():
        print(f"{name:<28} {desc}")
    return 0


def main(argv=None):
    parser = _parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    handler = {"mesh": _cmd_mesh, "validate": _cmd_validate, "run": _cmd_run, "scenes": _cmd_scenes}[args.command]
    try:
        return handler(args) or 0
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except (ValueError, FileNotFoundError) as exc:  # bad input: a clear message, no traceback
        print(f"femshell {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
