"""
The compiled kernel: the packed state, the step of the coach chain and its drivers.

Every module of this folder is compiled with numba (``compiler.py``: cached by the content
of all of them, so the folder IS the list of kernel sources) and nothing outside it defines a
jitted function:

- ``layout.py``: the packed arrays the kernel advances in place, row by row;
- ``step.py``: the pieces of one step shared by both drivers (ROS2, active set, brakes,
  external forces, fault check, acceptance);
- ``fixed_step.py``: the fixed-step driver; ``adaptive.py``: the error-controlled driver;
  ``standstill.py``: the holding LCP of vehicles at rest;
- the compiled parts of the force laws: ``couplers.py``, ``brakes.py``, ``pneumatic.py``,
  ``resistance.py``, ``track.py``, ``traction.py`` (their Python-side model code is in the
  physics module of the same name).
"""
