"""Train the reaction classifier and write the model and its report (paper section 2.3).

    python -m tools.train_classifier                 # the shipped model: reactive_anim/models/
    python -m tools.train_classifier --quick         # about 20 s; writes out/reaction_classifier.onnx
    python -m tools.train_classifier --quick --clips my_walk.bvh my_idle.bvh --out my_model.onnx

Simulates pushes on locomotion clips (default: the sample walk, run and idle), labels each by its
physical outcome (core/classify/outcome.py), trains our MLP on the extended and on the paper's nine features
and the paper's 9-9-4 net, ships the better of ours as ONNX with a Markdown report beside it, and
(full runs, where ../shared/mocap exists) adds the generalisation and real-capture figures.
Deterministic: the same seed and clips give the same model. Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from reactive_anim.core.classify.classifier import load_classifier
from reactive_anim.core.model.classes import CLASS_SLUGS
from reactive_anim.core.model.errors import ReactiveAnimError
from tools.classifier import real_mocap
from tools.classifier.pipeline import GROUPS, Config, Result, log_to_stderr, run
from tools.classifier.pushes import default_workers
from tools.classifier.report import write_report


def parser() -> argparse.ArgumentParser:
    assert __doc__ is not None
    p = argparse.ArgumentParser(prog="python -m tools.train_classifier", description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="fewer samples, one network size, no real-mocap figures")
    p.add_argument(
        "--clips", type=Path, nargs="+", help="locomotion BVH clips of your character (default: the samples)"
    )
    p.add_argument("--samples", type=int, help="pushes to simulate (default 40000, quick 1500)")
    p.add_argument("--seed", type=int, default=Config.seed)
    p.add_argument("--workers", type=int, default=default_workers(), help="simulation processes (default: 2)")
    p.add_argument("--out", type=Path, help="the .onnx to write (the report goes beside it, .md)")
    p.add_argument("--classes", help="comma-separated class slugs to keep (default: all 10)")
    p.add_argument("--max-strength", type=float, default=Config.max_strength, help="strongest push, N·s")
    return p


def config_from(args: argparse.Namespace) -> Config:
    changes: dict[str, object] = {"seed": args.seed, "workers": args.workers, "max_strength": args.max_strength}
    if args.clips:
        changes["clips"] = tuple(args.clips)
    if args.samples:
        changes["samples"] = args.samples
    if args.out:
        changes["out"] = args.out
    if args.classes:
        classes = tuple(c.strip() for c in args.classes.split(","))
        unknown = [c for c in classes if c not in CLASS_SLUGS]
        if unknown:
            raise ReactiveAnimError(f"unknown classes {', '.join(unknown)}; the classes are: {', '.join(CLASS_SLUGS)}")
        changes["classes"] = classes
    return Config.quick(**changes) if args.quick else Config(**changes)  # type: ignore[arg-type]


def real_mocap_figures(result: Result) -> tuple[real_mocap.Generalisation | None, list | None]:
    """Generalisation and real-capture figures for a full run on all classes, where the data is."""
    if result.config.samples < Config.samples or len(result.classes) != len(CLASS_SLUGS) or not real_mocap.available():
        return None, None
    start = time.perf_counter()
    classifier = load_classifier(result.config.out)
    log_to_stderr("generalisation: pushes on real walks and runs from ../shared/mocap")
    general = real_mocap.generalisation(classifier, result.config.seed, result.config.workers, GROUPS)
    captures = real_mocap.real_reactions(classifier)
    result.seconds["real_mocap"] = time.perf_counter() - start
    result.seconds["total"] += result.seconds["real_mocap"]
    return general, captures


def main(argv: list[str] | None = None) -> int:
    args = parser().parse_args(argv)
    try:
        config = config_from(args)
        result = run(config)
        general, captures = real_mocap_figures(result)
    except ReactiveAnimError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    report = config.out.with_suffix(".md")
    write_report(result, general, captures, report)
    shipped = result.shipped
    print(
        f"{config.out}: {shipped.name}, test accuracy {100 * shipped.test.accuracy:.2f} %, direction group "
        f"{100 * shipped.test.group_accuracy:.2f} %; report {report}; {result.seconds['total']:.0f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
