"""Benches: scripts that print figures (speed, agreement, segmentation quality) and make
the README's pictures. Run each from the repository root as ``python -m bench.NAME``,
which makes ``bench`` and the test data of ``testkit`` importable without path edits."""
