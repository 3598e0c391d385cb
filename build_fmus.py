"""Build the drillstring FMUs (the plant, the torsional controller and the top-drive controller,
FMI 2.0 co-simulation, each in the paper's scaled quantities and in SI units) and the closed
loops as SSP 1.0 packages.

Usage::

    python build_fmus.py [--gains out/design/gains.json [--design]] [--out build/]

The builder is :mod:`drillstring.apps.export` (``drillstring fmus`` where the package is
installed); this file is its command in the source checkout.
"""

from drillstring.apps.export.cli import export_main

if __name__ == "__main__":
    raise SystemExit(export_main(prog="build_fmus.py"))
