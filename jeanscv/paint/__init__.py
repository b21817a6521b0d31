"""Stage paint: a fit -> pictures.

Takes the photo, a :class:`~jeanscv.fitting.fitter.FitResult` and its
:class:`~jeanscv.subject.silhouettes.Silhouette`; gives RGB(A) pictures: the garment
painted on the photo (denim or flat) or on the silhouette drawing, and the paper's figure.
Public names: :func:`jeanscv.paint.figures.composite`, :func:`~jeanscv.paint.figures.figure`,
:func:`~jeanscv.paint.figures.draw_figure`, :func:`~jeanscv.paint.figures.draw_garment`;
the painting itself is in :mod:`~jeanscv.paint.compositing`, :mod:`~jeanscv.paint.denim`
and :mod:`~jeanscv.paint.denim_details`. Imports the stages below it (io, subject, fitting).
"""
