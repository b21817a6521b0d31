"""Stage io: bytes in and out, below every other stage.

Takes files (photos, RAW, SVG) and gives pixels; takes pictures and reports and writes
them atomically. Public names: :func:`jeanscv.io.image.load_image` and
:class:`~jeanscv.io.image.LoadedImage` (decoding, EXIF, RAW), :mod:`jeanscv.io.svg`
(SVG silhouettes), :mod:`jeanscv.io.write` (image, JSON, SVG, GIF outputs),
:func:`jeanscv.io.files.open_regular`. Imports only :mod:`jeanscv.errors` and
:mod:`jeanscv.geometry`.
"""
