"""``wbmp batch``: many motions at once, into a motion library folder (docs/batch.md).

- :mod:`wbmp.batch.items`: the batch file (sentences, spec files or JSONL) and its jobs;
- :mod:`wbmp.batch.worker`: one job, exactly what ``wbmp solve --out`` does, as an index record;
- :mod:`wbmp.batch.backends`: the local process pool and Ray;
- :mod:`wbmp.batch.index`: ``index.jsonl``, the resume rule, ``summary.md``;
- :mod:`wbmp.batch.run`: the checks before any work and the run itself.
"""
