"""The drivers (what drives A): the :class:`~sim.drivers.policy.Driver` protocol, the policy
observation, and the learned, planning, IDM and callable drivers; the driver-format registry
(:mod:`sim.drivers.formats`) and the baselines' (:mod:`sim.drivers.baselines`).

Importing the package imports none of its modules: the built-in driver formats are
``"module:attr"`` entries of :data:`sim.drivers.formats.FORMATS`, imported when first read, so
``import sim.drivers`` stays light (no SciPy, no SUMO). A new driver type is one module here and
one entry in that registry (or one :func:`~sim.drivers.formats.register_format` call from one's
own code).
"""
