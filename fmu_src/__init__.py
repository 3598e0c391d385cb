"""The FMU sources, installed as the package data ``drillstring.fmu_src``: the FMU scripts, their
shared modules and the C front layer (``fmi_front/``). They are bundled into each FMU's
``resources/`` and binaries by :mod:`drillstring.apps.export`, where they are top-level modules:
they are not imported as a package.
"""
