"""Test data for the tests and the benches, kept out of the ``jeanscv`` package.

``synthetic``: a zoo of procedurally drawn silhouettes (and random creatures);
``synthetic_photos``: photos composed from silhouettes and real textures, with exact
masks; ``real_photo_set``: the shared real photos and their reference masks;
``upright_shapes``: shapes whose garment should hang upright.

Importable from the repository root: the tests get it through pytest's ``pythonpath``
(pyproject.toml), the benches by running as ``python -m bench.NAME`` there.
"""
