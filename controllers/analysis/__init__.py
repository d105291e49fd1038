"""Stability and response analysis of the joint and task-space loops (paper section 4).

Outer loop, per task axis (eqs. 21-27): the integrated pose is
``x_c[k+1] = x_c[k] + T K_I e[k]`` (Fig. 7's ``T K_I / (z - 1)``, forward
Euler), the inner loop is ``d`` samples of delay (eq. 21: ``d = 1``), the
sensor a gain ``K``. With ``g = K K_I`` the loop gain is::

    L(z) = g T N(z) / ((z - 1) z^d),   N = 1 (I, eq. 22),  N = z + c (PI, c = 0.2)

and the characteristic polynomial ``P(z) = (z - 1) z^d + g T N(z)`` is linear
in ``g``: ``P = A + g B``. For ``d = 1`` (eq. 24) it is second order and the
Jury conditions ``|a0| < 1``, ``P(1) > 0``, ``P(-1) > 0`` give closed forms:

* I:  ``z^2 - z + g T``:  ``g T < 1``,  so ``g < 1/T = 16.67`` for T = 60 ms;
* PI: ``z^2 + (g T - 1) z + c g T``: ``g < min(1/(c T), 2/((1 - c) T))``
  = ``min(83.3, 41.7) = 41.7``.

For any order :func:`stability_limit` finds the first gain at which a root
reaches the unit circle (``z = 1``, ``z = -1`` or a complex pair: zero of the
imaginary part of ``-A/B`` on the circle, refined with ``brentq``) and checks
it with the poles (:func:`schur_stable`) just above.

The "real inner loop" replaces the delay by the discretised joint controller
and the identified plant (ZOH at 1 ms), lifted to the outer period
(``Phi = A_cl^n``, ``Gamma = sum A_cl^i B_cl``), mapped to the task space
with the IK Jacobian at home.

The modules: :mod:`.outer_delay` (the delay model above), :mod:`.inner` (one
continuous joint loop), :mod:`.lifted` (the real inner loops, lifted); each name is
imported from the module that defines it.

Imports numpy and scipy; python-control (``control``) on use, for the root
loci and step information (``analyze``). The pieces every run's preflight
uses stay numpy (the discretisation, the realisation, the stability
limit): each says why and is tested against python-control.
"""
