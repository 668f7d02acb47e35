"""The drivers: the Policy protocol, the policy observation, and the learned, planning, IDM and
callable drivers; the driver-format registry (:mod:`sim.drivers.formats`) and the baselines'
(:mod:`sim.drivers.baselines`).

Importing the package imports every module of its folder, so that each driver module's
:func:`~sim.drivers.formats.register_format` runs: a new driver type is one module here, with no
edit elsewhere.
"""

import importlib
import pkgutil

for _info in sorted(pkgutil.iter_modules(__path__), key=lambda m: m.name):
    importlib.import_module(f"{__name__}.{_info.name}")
