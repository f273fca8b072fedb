"""``wristmark marker print|family``: printable sleeves (cvs.marker.print_sheet, cvs.marker.family).

``wristmark marker print --marker FILE --out sleeve.svg|sleeve.pdf [--force]`` writes the page
(2 pi r wide plus margins, the sleeve's z extent tall, a 10 mm scale bar and the marker file's
name) for a lab to print on label film at 100 % and wrap around the arm. An existing --out is
kept unless --force.

``wristmark marker family --arms N --out DIR [--bands-per-side 2|3] [--sheet pdf|svg] [--names A,B]
[--force]`` writes N coded marker files ``DIR/armK.yaml`` (or ``NAME.yaml``; each naming its arm)
of one shipped sleeve family and their sheets ``DIR/armK.pdf``: no sleeve's code window can be
read as another's. Existing files are kept (nothing written) unless --force.
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
    fa = sub.add_parser("family", help="write N coded marker files (and sheets) of one sleeve family, one per arm")
    fa.add_argument("--arms", required=True, type=int, metavar="N", help="number of arms (sleeves)")
    fa.add_argument("--out", required=True, metavar="DIR",
                    help="output folder: armK.yaml and armK.pdf per arm (created)")
    fa.add_argument("--bands-per-side", type=int, choices=(2, 3), default=None, metavar="B",
                    help="code bands on each side of the checker rows: 2 (10.4 mm sleeve, up to 2 arms) or "
                         "3 (13.0 mm, more arms); default the shortest sleeve that has N arms")
    fa.add_argument("--sheet", choices=("pdf", "svg"), default="pdf", help="format of the sheets (default pdf)")
    fa.add_argument("--names", metavar="A,B,...", help="the arms' names, one per arm (default arm0,arm1,...); "
                    "the files are NAME.yaml and NAME.pdf")
    add_force_argument(fa)
    set_example(fa, "wristmark marker family --arms 2 --out runs/tour/family")
    set_example(p, "wristmark marker print --marker configs/marker_coded.yaml --out runs/tour/sleeve.pdf")


def run(args: argparse.Namespace) -> int:
    if args.action == "family":
        return _family(args)
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


def _family(args: argparse.Namespace) -> int:
    from wristmark.cvs.marker.family import family_markers, marker_file_text
    from wristmark.cvs.marker.print_sheet import write_pdf, write_svg

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out}: exists and is not a folder")
    if not out.parent.is_dir():
        raise InputError(f"{out.parent}: folder not found")
    names = None if args.names is None else [n.strip() for n in args.names.split(",")]
    markers = family_markers(args.arms, names=names, bands_per_side=args.bands_per_side)  # InputError: too many
    files = [(out / f"{m.arm}.yaml", out / f"{m.arm}.{args.sheet}") for m in markers]
    if not args.force:  # refuse existing outputs before writing anything
        claim_outputs(files=[f for pair in files for f in pair])
    out.mkdir(exist_ok=True)
    write = write_svg if args.sheet == "svg" else write_pdf
    for m, (yaml_path, sheet) in zip(markers, files):
        yaml_path.write_text(marker_file_text(m, f"Sleeve '{m.arm}' of a {args.arms}-arm family "
                                                 f"(wristmark marker family; docs/marker_code.md \"Families\")."))
        write(m, sheet, yaml_path.name)
        print(f"wrote {yaml_path} and {sheet} (arm '{m.arm}'; print at 100 %)")
    return 0
