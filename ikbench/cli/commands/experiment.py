"""``ikbench experiment design|run|analyze|power``: the pointing study (Lucny et al., ICSR
2025) from trial lists to the analysis."""

from __future__ import annotations

import argparse

from ikbench.cli.commands.view import host_value
from ikbench.cli.values import INPUT_FILE, OUTPUT, Number
from ikbench.core.defaults import EXPERIMENT_METHOD
from ikbench.studies.folders import default_output

DEFAULT_OUTPUT = default_output("experiment")

HELP = ("experiment design|run|stimuli|analyze|power: the pointing study with NICO's gaze and "
        "pointing cues (trial lists, playback, simulated participants, analysis)")
DESCRIPTION = (
    "The truncated-pointing experiment of Lucny et al. (ICSR 2025): NICO's arm moves toward "
    "one of the touchscreen targets and stops at a fraction of its path; the head gives a "
    "gaze cue (G gaze only, P pointing only, GP pointing with congruent gaze, I pointing "
    "with incongruent gaze); the participant touches the target they predict. "
    "'design' writes one trial list per participant and design.json; 'run' plays them "
    "(simulated participants, the bus emulator or the robot) and appends every answer to "
    "responses.csv (--online: a browser page with the robot drawn from the participant's seat; "
    "--touchscreen: the lab's touchscreen page answers the robot's trials); 'stimuli' writes "
    "every stimulus as a video; 'analyze' writes hit rates with Wilson intervals, a mixed-effects "
    "logistic model, the hypotheses' contrasts and figures; 'power' simulates studies to "
    "find the participants needed. docs/experiment.md.")


def arguments(parser: argparse.ArgumentParser) -> None:
    sub = parser.add_subparsers(dest="action", metavar="ACTION", required=True)
    design = sub.add_parser("design", help="write trial lists and design.json",
                            description="Write DIR/participant_XX/trials.csv for each "
                            "participant, DIR/trajectories/METHOD/ (the arm's trajectory to "
                            "every target) and DIR/design.json. The same seed writes the same "
                            "files. docs/experiment.md.")
    _design_arguments(design)
    play = sub.add_parser("run", help="play the trial lists and record responses",
                          description="Play every participant's trial list and append each "
                          "response (synced) to participant_XX/responses.csv; an interrupted "
                          "run resumes where it stopped, repeating no trial. --simulate: "
                          "model observers answer (labelled simulated everywhere); "
                          "--emulator or --robot-port: NICO's head and arm on the Dynamixel "
                          "bus, answers from --answers FILE, the terminal or (--touchscreen) the "
                          "lab's touchscreen page; --online: a local web server whose page "
                          "plays the trials with the robot drawn from the participant's seat "
                          "and records each click (docs/experiment-browser.md).")
    _run_arguments(play)
    stimuli = sub.add_parser("stimuli", help="every stimulus as a video (GIF) + manifest",
                             description="Write every distinct (target, condition, fraction, "
                             "gaze_target) of DIR's trials as an animated GIF from the "
                             "participant's viewpoint (the motion the online page plays), "
                             "per --method, with OUT/manifest.csv. docs/experiment-browser.md.")
    stimuli.add_argument("folder", metavar="DIR", help="the experiment folder")
    stimuli.add_argument("--method", default=None, metavar="M1,M2,...",
                         help="methods whose arm trajectories play (default: the design's)")
    stimuli.add_argument("--viewpoint-mm", default=None, metavar="X,Y,Z",
                         help="the participant's eyes [mm, torso frame] (default: "
                         "design.json's viewpoint_mm)")
    stimuli.add_argument("--hold", type=Number("a duration [s]", 0, 30), default=1.0,
                         metavar="S", help="how long the stop frame is held [s] (default 1)")
    stimuli.add_argument("--output", required=True, metavar="OUT", type=OUTPUT,
                         help="where the videos and manifest.csv go (replaced whole)")
    analyze = sub.add_parser("analyze", help="rates, model, contrasts, figures",
                             description="Read DIR's design and responses and write "
                             "analysis.md, analysis.csv, contrasts.csv, model.csv, "
                             "confusion.csv, observers.csv and figures into DIR/analysis "
                             "(or --output).")
    analyze.add_argument("folder", metavar="DIR", help="the experiment folder")
    analyze.add_argument("--output", default=None, metavar="DIR", type=OUTPUT,
                         help="where the analysis goes (default DIR/analysis)")
    power = sub.add_parser("power", help="participants needed, by simulation",
                           description="Simulate whole studies of a design (DIR from "
                           "'experiment design') with model observers and report, per number "
                           "of participants, the share of studies in which a hypothesis' test "
                           "is significant (power, Wilson 95 % interval); also the "
                           "false-positive rate under a null model (every cue equally noisy, "
                           "no participant differences).")
    power.add_argument("folder", metavar="DIR", help="a design folder (experiment design)")
    power.add_argument("--participants", default="4,8,12,16,20", metavar="N1,N2,...",
                       help="numbers of participants to simulate (default 4,8,12,16,20)")
    power.add_argument("--repetitions", type=int, default=100,
                       help="simulated studies per number (default 100)")
    power.add_argument("--hypothesis", choices=("H1", "H2"), default="H1",
                       help="H1: GP beats P (multimodal superiority); H2: under I answers "
                       "follow the gaze (ocular primacy) (default H1)")
    _model_arguments(power)
    power.add_argument("--output", default=None, metavar="DIR", type=OUTPUT,
                       help="where power.csv and power.png go (default DIR/power)")
    for action in (design, play, stimuli, analyze, power):
        action.set_defaults(func=run)


def _design_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--participants", type=int, default=20,
                        help="participants, one trial list each (default 20)")
    parser.add_argument("--seed", type=int, default=1, help="seed of every random choice")
    parser.add_argument("--conditions", default="G,P,GP,I", metavar="C1,C2,...",
                        help="cues, any of G (gaze only), P (pointing only), GP (pointing and "
                        "congruent gaze), I (pointing and incongruent gaze) (default all)")
    parser.add_argument("--fractions", default="0.6,0.8", metavar="F1,F2,...",
                        help="where the arm stops, as shares of the fingertip's path length, "
                        "each in (0, 1] (default 0.6,0.8)")
    parser.add_argument("--goals", default=None, metavar="FILE", type=INPUT_FILE,
                        help="a targets file of NICO's right arm whose touch poses are the "
                        "goals (default NICO's seven)")
    parser.add_argument("--method", default=EXPERIMENT_METHOD,
                        help="the method whose trajectories the arm plays (default "
                        f"{EXPERIMENT_METHOD})")
    parser.add_argument("--repeats", type=int, default=5,
                        help="trials per target in each cell (default 5: 35 per cell)")
    parser.add_argument("--incongruent-trials", type=int, default=None, metavar="N",
                        help="trials in each I cell (default: --repeats per target; the "
                        "authors had 12)")
    parser.add_argument("--layout", choices=("blocked", "interleaved"), default="blocked",
                        help="blocked: one block per cell (the authors'); interleaved: cells "
                        "mixed in --blocks blocks")
    parser.add_argument("--blocks", type=int, default=5,
                        help="blocks of an interleaved layout (default 5)")
    parser.add_argument("--order", choices=("latin", "fixed"), default="latin",
                        help="block orders across participants: a balanced Latin square "
                        "(default) or the given order for all")
    parser.add_argument("--incongruent-rule", choices=("nearest", "authors", "random"),
                        default="nearest",
                        help="the gaze target of an I trial: the nearest other target "
                        "(default), the authors' pairs, or any other target")
    parser.add_argument("--practice", type=int, default=3,
                        help="practice trials first (GP at the largest fraction; default 3)")
    parser.add_argument("--duration", type=float, default=None, metavar="S",
                        help="the arm's forward motion over the whole path [s] (default 2, "
                        "the authors')")
    parser.add_argument("--gaze-lead", type=float, default=None, metavar="S",
                        help="the head moves this long before the arm [s] (default 0.5)")
    parser.add_argument("--output", default=DEFAULT_OUTPUT, metavar="DIR", type=OUTPUT,
                        help=f"the experiment folder (default {DEFAULT_OUTPUT})")


def _model_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--noise-deg", default="gaze=3,pointing=6,position=6",
                        metavar="gaze=S,pointing=S,position=S",
                        help="each cue's angular noise (sd) as the participant sees it [deg] "
                        "(default gaze=3,pointing=6,position=6)")
    parser.add_argument("--lapse", type=float, default=0.02,
                        help="probability of a random answer (default 0.02)")
    parser.add_argument("--participant-sd", type=float, default=0.2,
                        help="log-sd of each participant's noise multiplier (default 0.2)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the simulation")


def _run_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("folder", metavar="DIR", help="the experiment folder")
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument("--simulate", action="store_true",
                       help="simulated participants (model observers) answer")
    where.add_argument("--emulator", action="store_true",
                       help="play on the Dynamixel bus emulator (head and arm)")
    where.add_argument("--robot-port", default=None, metavar="PORT",
                       help="play on NICO (serial port, e.g. /dev/ttyUSB0)")
    where.add_argument("--online", action="store_true",
                       help="serve the online study: the page draws the robot from the "
                       "participant's seat and records each click (--port, --host)")
    parser.add_argument("--touchscreen", action="store_true",
                        help="with --emulator/--robot-port: the answers come from the lab's "
                        "touchscreen page (served on --port)")
    parser.add_argument("--port", type=Number("a TCP port", 0, 65535, integer=True,
                                              shown="from 0 to 65535"), default=8090,
                        help="--online/--touchscreen: the web server's TCP port (default 8090;"
                        " 0: any free one)")
    parser.add_argument("--host", default="127.0.0.1", type=host_value,
                        help="--online/--touchscreen: the interface to listen on (default "
                        "127.0.0.1, this machine only; 0.0.0.0: every interface)")
    parser.add_argument("--no-browser", action="store_true",
                        help="--online/--touchscreen: do not open a browser")
    parser.add_argument("--viewpoint-mm", default=None, metavar="X,Y,Z",
                        help="--online: the participant's eyes [mm, torso frame] (default: "
                        "design.json's viewpoint_mm)")
    parser.add_argument("--answers", default=None, metavar="FILE", type=INPUT_FILE,
                        help="answers for --emulator/--robot-port (CSV: participant, trial, "
                        "answer_target, touch_x_px, touch_y_px, reaction_s; default: typed)")
    parser.add_argument("--participant", default=None, metavar="N1,N2,...",
                        help="play only these participants (default all)")
    _model_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from ikbench.cli.options import begin

    action = {"design": _design, "run": _play, "stimuli": _stimuli, "analyze": _analyze,
              "power": _power}
    return action[args.action](args, begin)


def _design(args: argparse.Namespace, begin) -> int:  # type: ignore[no-untyped-def]
    from pathlib import Path

    from ikbench.core.io import check_folder_writable, check_writable
    from ikbench.experiment.design import (
        DesignSpec,
        build,
        check_conditions,
        parse_fractions,
        parse_list,
    )
    from ikbench.experiment.layout import load_goals

    spec = DesignSpec(
        participants=args.participants, seed=args.seed,
        conditions=check_conditions(parse_list(args.conditions, "--conditions")),
        fractions=parse_fractions(args.fractions),
        goals=load_goals(args.goals) if args.goals else None, repeats=args.repeats,
        incongruent_trials=args.incongruent_trials, layout=args.layout, blocks=args.blocks,
        order=args.order, incongruent_rule=args.incongruent_rule, practice=args.practice,
        method=args.method, duration_s=args.duration, gaze_lead_s=args.gaze_lead)
    spec.validate()
    check_folder_writable(args.output)
    check_writable(Path(args.output) / "design.json")
    begin(args)
    design = build(spec)
    design.write(args.output)
    trials = design.record["trials_per_participant"]
    print(f"{spec.participants} trial lists of {trials} trials (+ {spec.practice} practice), "
          f"cells {', '.join(design.record['cells'])}, trajectories by {spec.method}: "
          f"written to {args.output}")
    return 0


def _model(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    from ikbench.experiment.observers import ObserverModel, parse_noise

    model = ObserverModel(noise_deg=parse_noise(args.noise_deg), lapse=args.lapse,
                          participant_sd=args.participant_sd)
    model.validate()
    return model


def _play(args: argparse.Namespace, begin) -> int:  # type: ignore[no-untyped-def]
    from pathlib import Path

    from ikbench.experiment.play import PlaySpec, run

    only = None
    if args.participant is not None:
        try:
            only = tuple(int(w) for w in str(args.participant).split(","))
        except ValueError:
            from ikbench.core.errors import InputError

            raise InputError(f"--participant {args.participant!r}: give numbers, e.g. "
                             "1,2") from None
    from ikbench.experiment.touchscreen import check_touchscreen

    check_touchscreen(args.touchscreen, args.emulator, args.robot_port, args.answers)
    _viewpoint(args)                          # checked whatever the back-end
    if args.online:
        return _online(args, only, begin)
    backend = "simulated" if args.simulate else "emulator" if args.emulator else "robot"
    spec = PlaySpec(Path(args.folder), backend=backend, model=_model(args), seed=args.seed,
                    port=args.robot_port, answers=Path(args.answers) if args.answers else None,
                    only=only)
    spec.validate()
    begin(args)
    if args.touchscreen:
        result = _touchscreen(args, spec)
    elif backend == "emulator":
        from ikbench.experiment.play import emulated

        with emulated() as port:
            result = run(spec, emulator_port=port)
    else:
        result = run(spec)
    table = result.table
    print(f"{int(table['recorded_now'].sum())} responses recorded now "
          f"({int(table['recorded_before'].sum())} before) for {len(table)} participants "
          f"({backend}) in {args.folder}")
    return 0


def _analyze(args: argparse.Namespace, begin) -> int:  # type: ignore[no-untyped-def]
    from pathlib import Path

    from ikbench.core.io import check_writable
    from ikbench.experiment.design import read_design
    from ikbench.experiment.study import analyze_folder

    read_design(args.folder)
    out = Path(args.output) if args.output else Path(args.folder) / "analysis"
    check_writable(out / "analysis.md")
    begin(args)
    summary = analyze_folder(Path(args.folder), out)
    print(summary)
    return 0


def _power(args: argparse.Namespace, begin) -> int:  # type: ignore[no-untyped-def]
    from pathlib import Path

    from ikbench.core.io import check_writable
    from ikbench.experiment.design import read_design
    from ikbench.experiment.study import parse_sizes, power_study

    read_design(args.folder)
    sizes = parse_sizes(args.participants, args.repetitions)
    model = _model(args)
    out = Path(args.output) if args.output else Path(args.folder) / "power"
    check_writable(out / "power.csv")
    begin(args)
    print(power_study(Path(args.folder), out, model, sizes, args.repetitions, args.hypothesis,
                      args.seed))
    return 0


def _viewpoint(args: argparse.Namespace):  # type: ignore[no-untyped-def]
    from ikbench.experiment.study_view import parse_viewpoint

    return None if args.viewpoint_mm is None else parse_viewpoint(args.viewpoint_mm)


def _open(url: str, args: argparse.Namespace) -> None:
    print(f"serving {url} (Ctrl-C stops)", flush=True)
    if not args.no_browser:
        import webbrowser

        webbrowser.open(url)


def _online(args: argparse.Namespace, only, begin) -> int:  # type: ignore[no-untyped-def]
    import time
    from pathlib import Path

    from ikbench.experiment.design import read_design
    from ikbench.experiment.online import OnlineStudy
    from ikbench.experiment.study_view import StudyView
    from ikbench.experiment.web import FolderLock, StudyServer

    folder = Path(args.folder)
    read_design(folder)
    viewpoint = _viewpoint(args)
    begin(args)
    with FolderLock(folder):
        study = OnlineStudy(folder, StudyView(folder, viewpoint), only)
        if only is not None and len(only) != len(study.participants):
            from ikbench.core.errors import InputError

            raise InputError(f"--participant {args.participant}: not all in {folder} "
                             f"({', '.join(sorted(study.participants)) or 'none of them'})")
        with StudyServer(study, args.host, args.port) as server:
            url = server.url + (f"?participant={only[0]:02d}" if only and len(only) == 1
                                else "")
            _open(url, args)
            try:
                while True:
                    time.sleep(3600)
            except KeyboardInterrupt:
                print("stopped; every response is in participant_XX/responses.csv")
    return 0


def _touchscreen(args: argparse.Namespace, spec):  # type: ignore[no-untyped-def]
    import contextlib

    from ikbench.core.robot import load_robot
    from ikbench.experiment.design import read_design
    from ikbench.experiment.head import load_head
    from ikbench.experiment.play import BusPresenter, emulated, run
    from ikbench.experiment.study_view import design_goals
    from ikbench.experiment.touchscreen import (
        TouchscreenApp,
        TouchscreenPresenter,
        browser_answers,
    )
    from ikbench.experiment.web import FolderLock, StudyServer

    record = read_design(spec.folder)
    goals = design_goals(record)
    app = TouchscreenApp(goals, float(record.get("response_window_s", goals.response_window_s)))
    with contextlib.ExitStack() as stack:
        stack.enter_context(FolderLock(spec.folder))
        server = stack.enter_context(StudyServer(app, args.host, args.port))
        _open(server.url, args)
        port = stack.enter_context(emulated()) if args.emulator else args.robot_port
        inner = BusPresenter(spec.folder, port, spec.backend, load_robot(), load_head(),
                             browser_answers(app), spec.log)
        return run(spec, emulator_port=port if args.emulator else None,
                   presenter=TouchscreenPresenter(inner, app))


def _stimuli(args: argparse.Namespace, begin) -> int:  # type: ignore[no-untyped-def]
    from pathlib import Path

    from ikbench.core.io import check_folder_writable, check_writable
    from ikbench.experiment.design import parse_list, read_design
    from ikbench.experiment.stimuli import export
    from ikbench.experiment.study_view import StudyView

    folder = Path(args.folder)
    read_design(folder)
    viewpoint = _viewpoint(args)
    methods = parse_list(args.method, "--method") if args.method else None
    if methods:
        from ikbench.experiment.design import check_method

        for name in methods:
            check_method(name)
    check_folder_writable(args.output)
    check_writable(Path(args.output) / "manifest.csv")
    begin(args)
    table = export(folder, Path(args.output), StudyView(folder, viewpoint), methods,
                   hold_s=args.hold, log=lambda line: None)
    print(f"{len(table)} stimulus videos ({int(table['frames'].sum())} frames) and "
          f"manifest.csv written to {args.output}")
    return 0
