"""Stage subject: photo -> subject mask -> :class:`Silhouette`.

Takes decoded pixels (from :mod:`jeanscv.io`), and clicks where a person gave them;
gives one framed :class:`~jeanscv.subject.silhouettes.Silhouette` per object (the mask,
its contour, the 256x256 canvas ``S`` the fit takes, and the framing back to the photo).
Public names: :func:`~jeanscv.subject.extraction.extract_silhouette` and
:func:`~jeanscv.subject.extraction.extract_silhouettes`, :class:`Silhouette`,
:func:`~jeanscv.subject.silhouettes.read_svg`, :func:`~jeanscv.subject.silhouettes.load_mask`,
:func:`~jeanscv.subject.drawing.silhouette_from_drawing`, the clicks model
(:mod:`jeanscv.subject.clicks`), segmentation (:func:`jeanscv.subject.photo.segment`,
:class:`jeanscv.subject.interactive.ClickSession`) and silhouette plugins
(:mod:`jeanscv.subject.plugins`). Imports only the shared modules and :mod:`jeanscv.io`.
Its modules are imported one by one (segmentation loads OpenCV): this file imports none.
"""
