"""``wristmark marker print``: the unrolled sleeve of a marker file at 1:1 (cvs.marker.print_sheet).

``wristmark marker print --marker FILE --out sleeve.svg|sleeve.pdf [--force]`` writes the page
(2 pi r wide plus margins, the sleeve's z extent tall, a 10 mm scale bar and the marker file's
name) for a lab to print on label film at 100 % and wrap around the arm. An existing --out is
kept unless --force.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from wristmark.cli.common_options import add_config_option, add_force_argument, set_example
from wristmark.models.config_files import find_config
from wristmark.models.errors import InputError
from wristmark.rig.recording.output_dir import claim_outputs


def add_arguments(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", required=True, metavar="ACTION")
    pr = sub.add_parser("print", help="write the unrolled sleeve at 1:1 (SVG or PDF)")
    add_config_option(pr, "--marker", required=True, note="e.g. configs/marker_coded.yaml")
    pr.add_argument("--out", required=True, metavar="FILE.pdf", help="output file: .svg or .pdf")
    add_force_argument(pr)
    set_example(pr, "wristmark marker print --marker configs/marker_coded.yaml --out runs/tour/sleeve.pdf")
    set_example(p, "wristmark marker print --marker configs/marker_coded.yaml --out runs/tour/sleeve.pdf")


def run(args: argparse.Namespace) -> int:
    from wristmark.cvs.marker.print_sheet import write_pdf, write_svg
    from wristmark.models.marker import MarkerModel

    out = Path(args.out)
    kind = out.suffix.lower()
    if kind not in (".svg", ".pdf"):
        raise InputError(f"--out must end in .svg or .pdf, got '{out.name}'")
    if not args.force:  # refuse an existing --out (checked only: written over at the end)
        claim_outputs(files=[out])
    if not out.parent.is_dir():
        raise InputError(f"{out.parent}: folder not found")
    marker_path = find_config(args.marker)  # a missing configs/NAME.yaml is the shipped file
    if not marker_path.is_file():
        raise InputError(f"{marker_path}: marker file not found")
    marker = MarkerModel.load(marker_path)
    (write_svg if kind == ".svg" else write_pdf)(marker, out, marker_path.name)
    print(f"wrote {out} ({kind[1:].upper()}, 1:1: print at 100 %)")
    return 0
