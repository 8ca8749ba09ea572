"""
The compiled kernel: the packed state, the step of the coach chain and its drivers.

Every module of this folder is compiled with numba (``compiler.py``: cached by the content
of all of them, so the folder IS the list of kernel sources) and nothing outside it defines a
jitted function:

- ``layout.py``: the packed arrays the kernel advances in place, row by row;
- ``step.py``: the pieces of one step both drivers share (brake system, external forces,
  fault check, acceptance), over the method's parts, one per module: ``rosenbrock2.py`` (the
  Rosenbrock stages), ``coupler_rows.py`` (the couplers' force, slopes and stage weights),
  ``active_set.py`` (the vehicles held at rest) and ``standstill.py`` (their holding LCP);
- the drivers: ``fixed_step.py`` (fixed step) and ``adaptive.py`` (error-controlled);
- the compiled parts of the force laws: ``couplers.py``, ``brakes.py``, ``pneumatic.py``,
  ``resistance.py``, ``track.py``, ``traction.py`` (their Python-side model code is in the
  physics module of the same name).
"""
