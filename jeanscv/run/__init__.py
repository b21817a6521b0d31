"""Stage run: many inputs, above the pipeline.

Takes a list of inputs and an output folder; gives one picture, report and JSONL line
per input, one failing input never stopping the others. Public names:
:func:`jeanscv.run.distributed.run_on_dask` (a Dask cluster), and what the command's
workers and the Dask tasks share (:mod:`jeanscv.run.runner`: ``encode_picture``,
``report_text``, ``failure_reason``). ``_forkserver`` is what the command's fork server
preloads before it forks the ``-j`` workers. Calls :mod:`jeanscv.pipeline` and below.
"""
