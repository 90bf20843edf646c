"""``ikbench letters``: draw letters in the air (the paper's second experiment)."""

from __future__ import annotations


def register(subparsers) -> None:
    from ikbench.commands.run import add_run_arguments, add_start_pose_argument
    from ikbench.letters import DEFAULT_STEPS, PAPER_ITERATIONS, PAPER_START_POSE_DEG
    from ikbench.methods import available_methods

    methods = available_methods()
    pose = ",".join(f"{v:g}" for v in PAPER_START_POSE_DEG)
    parser = subparsers.add_parser(
        "letters",
        help="draw letters A-Z in the air with the fingertip (the paper's letter experiment)",
        description=(
            "Draw each letter on the frontal plane through the fingertip at the start pose, "
            "its box centred on the fingertip, read by a viewer facing the robot, the finger "
            "pointing along the plane normal (-1, 0, 0); no start/end pose or point terms. "
            "Same as `ikbench run --shape letter:LETTERS` with the paper's letter setting as "
            f"defaults: start pose {pose}, letters 300 mm high, n = {DEFAULT_STEPS}, weights "
            "c0=1, c1=50, c6=1, others 0, to which --weights changes apply (ours and ours-lm), "
            f"and for ours --stop none --max-iterations {PAPER_ITERATIONS} (best loss kept). "
            "--method ours-lm solves a letter in a fraction of a second, starting with every "
            "pose at the start pose. Writes OUTPUT/<method>/trajectory_<letter>.csv, "
            "table.csv, details.csv, run.json, shapes.png and report.md."
        ),
    )
    parser.add_argument("letters", help="letters A-Z, comma-separated, e.g. P or P,A,S")
    parser.add_argument("--size", type=float, default=None,
                        help="letter height [mm] (default 300)")
    parser.add_argument("--direction", default=None,
                        help="goal pointing directions: normal (default), tangent or x,y,z")
    add_start_pose_argument(parser, f"the paper's letter pose {pose}")
    parser.add_argument("--steps", type=int, default=None,
                        help=f"number of segments n per letter (default {DEFAULT_STEPS})")
    add_run_arguments(parser, methods, "results/letters")
    parser.set_defaults(func=run)


def run(args) -> int:
    from ikbench.commands.run import run as run_command
    from ikbench.letters import PAPER_ITERATIONS, PAPER_START_POSE_DEG

    if args.start_pose is None:
        args.start_pose = ",".join(f"{v:g}" for v in PAPER_START_POSE_DEG)
    if args.method == "ours":
        args.stop = args.stop or "none"
        args.max_iterations = args.max_iterations or PAPER_ITERATIONS
    return run_command(args, shape=f"letter:{args.letters}")
