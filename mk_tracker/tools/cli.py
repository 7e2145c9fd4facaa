"""The ``mk_tracker`` command: one entry point, one sub-command per tool.

Each sub-command lives in its own module, which defines ``configure_parser(parser)`` and
``run(args) -> int``.  Modules are imported only when their sub-command is used, so a
missing optional dependency of one tool does not break the others.
"""

from __future__ import annotations

import argparse
import importlib
import sys

# name -> (module, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "import": ("mk_tracker.bags.dataset_import",
               "turn a MOTChallenge or OTB folder into a rosbag2 bag"),
    "generate": ("mk_tracker.synthetic.scene_bag",
                 "write a seeded synthetic RGB+thermal scene with ground truth as a bag"),
    "process": ("mk_tracker.tools.pipeline",
                "run detection and tracking over a bag offline, without DDS"),
    "eval": ("mk_tracker.evaluation.eval_command",
             "score tracking results against ground truth and draw plots"),
    "demo": ("mk_tracker.tools.demo",
             "generate a scene, run both nodes over DDS, score and render the result"),
}


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="mk_tracker", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module_name, help_text) in SUBCOMMANDS.items():
        sp = sub.add_parser(name, help=help_text, description=help_text)
        sp.set_defaults(_module=module_name)
        try:
            module = importlib.import_module(module_name)
        except ImportError as exc:
            sp.set_defaults(_import_error=exc)
            continue
        module.configure_parser(sp)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "command", None):
        parser.print_help()
        return 2
    error = getattr(args, "_import_error", None)
    if error is not None:
        print(f"mk_tracker {args.command}: cannot load {args._module}: {error}", file=sys.stderr)
        return 2
    module = importlib.import_module(args._module)
    return int(module.run(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
