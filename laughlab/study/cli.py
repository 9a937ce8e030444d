"""``python -m laughlab study build|serve|simulate|analyze|power|assignments``: the perception study from stimuli to report."""
from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path

from laughlab.core.errors import LaughlabError, finite_number, first_line, one_line_parser, port_number

EPILOG = """\
from stimuli to a report:
  python -m laughlab experiment=stimuli hydra.run.dir=runs/stimuli
  python -m laughlab study build runs/stimuli                 -> runs/stimuli-study/
  python -m laughlab study serve runs/stimuli-study           -> http://127.0.0.1:8765/?participant=1
  python -m laughlab study analyze runs/stimuli-study/responses.sqlite   -> .../responses-report/
  python -m laughlab study power runs/stimuli-study --contrast laugh_energy:smile_only --effect 0.5
a recruitment panel (Prolific): give it the link ...?PROLIFIC_PID={{%PROLIFIC_PID%}}, the server gives each ID a
participant number; python -m laughlab study assignments runs/stimuli-study  -> who to pay (CSV)
"""


def _ints(text: str) -> list[int]:
    try:
        out = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"a comma-separated list of whole numbers (got {text!r})") from None
    if not out or min(out) < 2:
        raise argparse.ArgumentTypeError("every number of participants must be >= 2")
    return out


def parser() -> argparse.ArgumentParser:
    from laughlab.viewer.server import DEFAULT_PORT

    p = one_line_parser(prog="python -m laughlab study", epilog=EPILOG,
                                formatter_class=argparse.RawDescriptionHelpFormatter,
                                description="Run the perception study of experiment=stimuli: a jsPsych page, "
                                            "responses in SQLite, a mixed-model report, power by simulation.")
    sub = p.add_subparsers(dest="cmd", required=True)
    b = sub.add_parser("build", help="write the study folder (page, jsPsych, videos, design)")
    b.add_argument("stimuli_dir", help="a finished experiment=stimuli folder (stimuli.json, manifest.csv, orders/)")
    b.add_argument("--out", help="the study folder (default: STIMULI_DIR-study beside it)")
    b.add_argument("--questions", help="a preset name (laughlab, riddle) or a YAML file of questions and checks "
                                       "(default: the stimuli's preset; see laughlab/study/presets/)")
    b.add_argument("--overwrite", action="store_true", help="replace the files of an earlier study build (never a folder holding people's answers)")
    s = sub.add_parser("serve", help="serve the page and store every answer in SQLite as it arrives")
    s.add_argument("study_dir")
    s.add_argument("--db", help="the database (default: STUDY_DIR/responses.sqlite)")
    s.add_argument("--port", type=port_number, default=DEFAULT_PORT, help="port (a free one if it is taken)")
    s.add_argument("--host", default="127.0.0.1", help="address to listen on (0.0.0.0: the lab's other computers)")
    s.add_argument("--panel", action="store_true", help="participants come only through a recruitment site's link "
                                                        "(?PROLIFIC_PID=...): no number typed by hand is taken")
    m = sub.add_parser("simulate", help="simulated participants in headless Chromium do the whole study, "
                                        "answers drawn from a planted effect (a demo, and the tests)")
    m.add_argument("study_dir")
    m.add_argument("--participants", type=int, default=8, help="how many, all at once (8)")
    m.add_argument("--effects", default="", help="CONDITION=POINTS,... planted above the base rating "
                                                 "(e.g. laugh_energy=1)")
    m.add_argument("--db", help="the database (default: STUDY_DIR/simulated.sqlite; never serve's, so simulated "
                                "answers never mix with people's)")
    m.add_argument("--seed", type=int, default=0, help="seed of the simulated answers (0)")
    a = sub.add_parser("analyze", help="exclusions, means with CIs, mixed model, contrasts, figures")
    a.add_argument("source", help="responses.sqlite, or a CSV of answers, or a folder of them")
    a.add_argument("--out", help="the report folder (default: SOURCE's name + -report beside it)")
    a.add_argument("--design", help="the study folder, for CSV input: exclusion rules and condition order")
    a.add_argument("--overwrite", action="store_true", help="replace an earlier report whose files were changed or "
                                                             "added to (the added files are kept)")
    a.add_argument("--width", choices=("page", "column"), default="page",
                   help="the figures for a page (default) or 3.5 in wide for one column of a two-column paper, no "
                        "text under 7 pt")
    g = sub.add_parser("assignments", help="the panel IDs (Prolific, MTurk) the server gave participant numbers, "
                                           "with consent and finish times: for paying and approving (CSV)")
    g.add_argument("source", help="responses.sqlite, or the study folder holding it")
    g.add_argument("--out", help="write the CSV here (a new file) instead of printing it")
    w = sub.add_parser("power", help="participants needed to detect an effect (simulation, the same model)")
    w.add_argument("study_dir", help="a study folder (its design: conditions, stimuli, orders, scale)")
    w.add_argument("--contrast", required=True, help="A:B, e.g. laugh_energy:smile_only")
    w.add_argument("--effect", type=finite_number, required=True, help="A's rating above B's, in scale points")
    w.add_argument("--participants", type=_ints, default=[8, 12, 16, 24, 32], help="numbers to try (8,12,16,24,32)")
    w.add_argument("--sims", type=int, default=200, help="simulated studies per number (200)")
    w.add_argument("--alpha", type=float, default=0.05)
    w.add_argument("--target", type=float, default=0.8, help="the power wanted (0.8)")
    w.add_argument("--pilot", help="a pilot's report folder: its variance components and intercept")
    w.add_argument("--question", help="the pilot's question to take them from (default: the first)")
    w.add_argument("--seed", type=int, default=0)
    w.add_argument("--out", help="write power.csv and power.png here (default: STUDY_DIR/power)")
    return p


def main(args: list[str]) -> None:
    ns = parser().parse_args(args)
    try:
        _run(ns)
    except ModuleNotFoundError as exc:  # an optional dependency of the study
        if exc.name and exc.name.split(".")[0] in ("statsmodels", "playwright", "patsy"):
            raise LaughlabError(f"the study needs {exc.name.split('.')[0]}: pip install 'laughlab[study]'") from None
        raise


def _run(ns) -> None:
    if ns.cmd == "build":
        from laughlab.study.build import build

        out = build(ns.stimuli_dir, ns.out, ns.questions, ns.overwrite)
        from laughlab.study.design import identical_conditions, load_design

        same = identical_conditions(load_design(out))
        if same:   # the riddle preset's SS and LS: the role is not shown (a review: it was tested as an effect)
            print(f"study: note: {', '.join(f'{a} and {b}' for a, b in same)} show the same videos and the page does "
                  "not present what tells them apart (the riddle's Speaks/Listens role): study analyze will not test "
                  "their difference", file=sys.stderr)
        print(f"laughlab: study written to {out}/; serve it with: python -m laughlab study serve "
              f"{shlex.quote(str(out))}")
    elif ns.cmd == "serve":
        serve(ns)
    elif ns.cmd == "simulate":
        simulate(ns)
    elif ns.cmd == "analyze":
        from laughlab.study.analyze import analyze

        out = analyze(ns.source, ns.out, ns.design, ns.overwrite, ns.width)
        from laughlab.study.analyze import REPORT_FILES

        written = sorted(f.name for f in out.iterdir() if f.name in REPORT_FILES)   # (a review: it named 3 of 10)
        print(f"laughlab: report written to {out}/: README.md (read it first), "
              f"{', '.join(n for n in written if n != 'README.md')}")
    elif ns.cmd == "assignments":
        assignments(ns)
    else:
        run_power(ns)


def assignments(ns) -> None:
    """The panel IDs as CSV: external_id, participant, assigned_at, consent_at, declined_at, finished_at,
    sound_check."""
    import csv
    import io

    from laughlab.study import db as DB

    source = Path(ns.source).expanduser()
    path = source / DB.DEFAULT_NAMES["people"] if source.is_dir() else source
    if DB.participants_kind(path) is None:
        raise LaughlabError(f"no study database at {path}" + (" (no participant has opened the page yet)"
                                                                if source.is_dir() else ""))
    rows = DB.assignments(path)
    text = io.StringIO()
    w = csv.DictWriter(text, ["external_id", "participant", "assigned_at", "consent_at", "declined_at",
                              "finished_at", "sound_check"], lineterminator="\n")
    w.writeheader()
    w.writerows(rows)
    if not ns.out:
        sys.stdout.write(text.getvalue())
        return
    out = Path(ns.out).expanduser()
    if out.exists():
        raise LaughlabError(f"{out} exists; give another --out (it is never overwritten)")
    tmp = out.with_name(f".{out.name}.part")
    tmp.write_text(text.getvalue(), encoding="utf-8")
    tmp.replace(out)
    print(f"laughlab: {len(rows)} panel ID{'' if len(rows) == 1 else 's'} written to {out}", file=sys.stderr)


def _handler(httpd):
    """The server's handler class (the server holds it wrapped in a functools.partial)."""
    return getattr(httpd.RequestHandlerClass, "func", httpd.RequestHandlerClass)


def serve(ns) -> None:
    from laughlab.study.server import server

    httpd = server(ns.study_dir, ns.db, ns.port, ns.host, panel=ns.panel)
    from laughlab.viewer.server import serve_until_interrupted, shown_url

    everywhere = httpd.server_address[0] in ("0.0.0.0", "", "::")
    handler = _handler(httpd)
    n = len(handler.design["participants"])
    wide = "listening on every network: other computers open it at this computer's address; " if everywhere else ""
    link = "/?PROLIFIC_PID={{%PROLIFIC_PID%}}&STUDY_ID={{%STUDY_ID%}}&SESSION_ID={{%SESSION_ID%}}" if ns.panel \
        else "/?participant=1"
    who = "a recruitment site's link only, " if ns.panel else ""
    print(f"laughlab: serving {ns.study_dir} at {shown_url(httpd)}{link} ({who}participants 1..{n}; "
          f"{wide}answers into {handler.db}; Ctrl-C to stop)", flush=True)

    serve_until_interrupted(httpd)


def simulate(ns) -> None:
    """Serve the study on a free local port and let ``--participants`` simulated people do it at once."""
    import threading

    from laughlab.study import simulate as S
    from laughlab.study.design import load_design
    from laughlab.study.server import server

    study = Path(ns.study_dir).expanduser()
    design = load_design(study)
    if not 1 <= ns.participants <= len(design["participants"]):
        raise LaughlabError(f"--participants must be 1..{len(design['participants'])} (the design's rows)")
    effects = S.parse_effects(ns.effects, design)
    from laughlab.study import db as DB

    target = Path(ns.db).expanduser() if ns.db else study / DB.DEFAULT_NAMES["simulated"]
    made = [target.with_name(target.name + end) for end in ("", "-journal", "-wal", "-shm", ".rejected.log")]
    made = [f for f in made if not f.exists()]   # what this simulation creates; anything there before is kept
    httpd = server(study, ns.db, 0, quiet=True, participants="simulated")
    from laughlab.study.db import participants_stored

    db = _handler(httpd).db
    done = participants_stored(db)
    if done:   # a second simulation would add to (or skip) the first one's participants, of another plant or seed
        httpd.server_close()
        raise LaughlabError(f"{db} already holds {len(done)} simulated participants' answers; give another --db, or "
                            "delete it to simulate again")
    threading.Thread(target=httpd.serve_forever, daemon=True).start()
    try:
        url = f"http://127.0.0.1:{httpd.server_address[1]}"
        given = S.run_sync(url, design, list(range(1, ns.participants + 1)), S.planted(design, effects, seed=ns.seed))
    except BaseException as exc:   # Ctrl-C, Chromium gone: a review found the part-done database refusing the command again
        httpd.shutdown()
        httpd.server_close()
        for f in made:
            f.unlink(missing_ok=True)
        if S.browser_gone(exc):
            raise LaughlabError(f"Chromium stopped while the simulated participants worked ({first_line(exc)}); "
                                "nothing was kept: run the command again") from None
        raise
    httpd.shutdown()
    httpd.server_close()
    from laughlab.study.db import rows, store   # store: what was planted, so that the analysis can say what it should recover

    # the database's rows as its CSV export counts them: the ratings and attention answers, and one audio check a
    # participant (the line said "216 answers" of a CSV of 228 rows, a new-user review)
    kinds = [r["kind"] for r in rows(_handler(httpd).db)]
    n, checks = len(kinds) - kinds.count("audio_check"), kinds.count("audio_check")

    store(_handler(httpd).db, "simulation", {"effects": effects, "seed": ns.seed, "participants": len(given),
                                             **S.PLANTED_SPREAD})
    print(f"laughlab: {len(given)} simulated participants finished ({n} answers and {checks} audio checks, planted "
          f"{ns.effects or 'no effect'})"
          f" -> {_handler(httpd).db}; analyze it with: python -m laughlab study analyze "
          f"{shlex.quote(str(_handler(httpd).db))}")


def run_power(ns) -> None:
    import csv

    from laughlab.study import power as W
    from laughlab.study.design import load_design, scale_range

    if ns.sims < 1 or not 0 < ns.alpha < 1 or not 0 < ns.target < 1:
        raise LaughlabError("--sims must be >= 1, --alpha and --target between 0 and 1")
    a, sep, b = ns.contrast.partition(":")
    if not sep:
        raise LaughlabError(f"--contrast must be A:B (got {ns.contrast!r})")
    design = load_design(Path(ns.study_dir).expanduser())
    out = Path(ns.out).expanduser() if ns.out else Path(ns.study_dir).expanduser() / "power"
    W.check_out(out)   # before the simulations: they take minutes
    var, icpt, source, simulated = None, sum(scale_range(design)) / 2, "defaults", False   # the scale's middle (4)
    if ns.pilot:
        var, icpt, q, simulated = W.pilot_variance(ns.pilot, ns.question)
        source = f"pilot {ns.pilot} ({q}{', simulated participants' if simulated else ''})"
    W.check_effect(ns.effect, icpt, scale_range(design))   # before the simulations: they take minutes
    if W.near_end_note(ns.effect, icpt, scale_range(design)):
        print(W.near_end_note(ns.effect, icpt, scale_range(design)), file=sys.stderr, flush=True)
    rows = W.power(design, (a, b), ns.effect, ns.participants, ns.sims, ns.alpha, var, icpt, ns.seed,
                   progress=lambda m: print(m, file=sys.stderr, flush=True))
    if ns.sims < 100:   # a power of 0.8 from 5 simulations is 0.38-0.96 (Wilson): say so, not only in the CSV
        lo, hi = W.wilson(round(0.8 * ns.sims), ns.sims)
        print(f"power: note: with --sims {ns.sims} each power is only known roughly (0.8 would be {lo:.2f}-{hi:.2f}, "
              "95 % Wilson; ci_low and ci_high in power.csv); 200, the default, narrows that to about +-0.06",
              file=sys.stderr)
    W.check_out(out)
    out.mkdir(parents=True, exist_ok=True)
    title = f"{a} - {b} = {ns.effect:g} point{'' if abs(ns.effect) == 1 else 's'}; variances: {source}"
    parts = [out / ".power.csv.part", out / ".power.png.part"]
    try:
        with open(parts[0], "w", newline="", encoding="utf-8") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
            w.writeheader()
            w.writerows(rows)
        W.plot(parts[1], rows, ns.target, title)
        os.replace(parts[0], out / "power.csv")
        os.replace(parts[1], out / "power.png")
    finally:
        for part in parts:
            part.unlink(missing_ok=True)
    if simulated:
        print(f"power: note: the variances are from a report of simulated participants ({ns.pilot}): the planted "
              "model's spreads, not a pilot's", file=sys.stderr)
    print(f"laughlab: {W.verdict(rows, ns.target)} for {a} - {b} = {ns.effect:g} (alpha {ns.alpha:g}, Holm); "
          f"{out}/power.csv, power.png")
    hint = W.advice(rows, ns.target, ns.effect, len(design["participants"]))
    if hint:
        print(f"laughlab: {hint}")
