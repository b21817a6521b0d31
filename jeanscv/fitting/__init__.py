"""Stage fitting: a 256x256 canvas ``S`` -> a fitted garment polygon.

Takes the subject's canvas (a :class:`~jeanscv.subject.silhouettes.Silhouette`'s
``canvas``, or any ``S`` array; this stage never imports the subject stage) and a
:class:`~jeanscv.fitting.garments.Garment`; gives a :class:`~jeanscv.fitting.fitter.FitResult`
(canvas vertices, per-term losses, history, rule checks, posture). Public names:
:func:`jeanscv.fitting.fitter.fit`, :class:`~jeanscv.fitting.garments.Garment` and
``GARMENTS``, ``PRESETS`` (:mod:`~jeanscv.fitting.presets`), the loss
(:class:`~jeanscv.fitting.loss.JalgorithmLoss`, :func:`~jeanscv.fitting.loss.jalgorithm_terms`),
:func:`~jeanscv.fitting.checks.rule_report`, :func:`~jeanscv.fitting.posture.posture`.
``_fast`` holds the numba kernels. Imports only the shared modules and :mod:`jeanscv.io`.
Named ``fitting``, not ``fit``: ``jeanscv.fit`` is the public function, which a
subpackage of that name would replace once imported.
"""
