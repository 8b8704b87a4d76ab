"""sympy expressions as NumPy functions, without sympy's ``from numpy import *``.

``sympy.lambdify(..., modules="numpy")`` builds its namespace, the first time a process asks, with
``import numpy; from numpy import *; from numpy.linalg import *``, and NumPy 2's star import loads
every submodule that NumPy otherwise imports only on use (``numpy.f2py``, ``numpy.testing``,
``numpy.ma``, ...): about 0.13 s, which was 3 % of a whole ``charcurves fit`` process on a
1 000-sample record. :func:`numpy_function` gives the same function: the same printer (sympy's
``NumPyPrinter``, chosen because the numpy module is among the modules), the same NumPy objects
under the same names (NumPy's attributes with ``numpy.linalg``'s over them, as the star imports
give), without loading NumPy's other submodules.

Examples
--------
>>> import numpy as np, sympy as sp
>>> from charcurves._lambdify import numpy_function
>>> z = sp.Symbol("z")
>>> f = numpy_function([z], sp.tanh(3 * z) + sp.Heaviside(z) + sp.Abs(z))
>>> f(np.array([-1.0, 0.0, 2.0])).round(4).tolist()
[0.0049, 0.5, 3.0]
"""

from __future__ import annotations

__all__ = ["numpy_function"]


def numpy_function(symbols, expr, **kwargs):
    """``sympy.lambdify(symbols, expr, modules="numpy")``, its docstring left out (lambdify prints the
    expression a second time for it), without the star import of NumPy (module docstring)."""
    import numpy
    import sympy

    return sympy.lambdify(symbols, expr, modules=[numpy.linalg, numpy], docstring_limit=0, **kwargs)
