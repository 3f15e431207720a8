"""Benchmarks, reports and pages (the top layer: may use every other package).

* :mod:`~harness.reports.bench`, :mod:`~harness.reports.model_bench`,
  :mod:`~harness.reports.table_error`, :mod:`~harness.reports.glossy_noise`,
  :mod:`~harness.reports.dipole_bench`, :mod:`~harness.reports.dg_compare`: ``make bench`` and
  ``make dg-compare``;
* :mod:`~harness.reports.gonio`, :mod:`~harness.reports.stability`: round trip and hard cases;
* :mod:`~harness.reports.report`: ``make report``; :mod:`~harness.reports.regress`:
  ``make regress``; :mod:`~harness.reports.study` (+ :mod:`~harness.reports.dask_task`):
  ``make study``.
"""
