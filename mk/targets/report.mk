# The finish report (harness/reports/report.py): every finish (each analytic model family, tables at
# 0.5/1/2/5 deg, the dipole beside stock subsurface) against its expectation and its trace
# time against stock phong, plus the gonioreflectometer round trip and the stability suite,
# as one HTML page with plots and error maps. REPORT_ARGS passes options (see --help).
.PHONY: report report-quick

report: all venv ## One HTML page of every finish's error and cost, gonio round trip, stability: out/report/index.html
	$(PY) -m harness.reports.report $(REPORT_ARGS)

report-quick: all venv ## The same page at CI size (smaller renders, one timing round, quick gonio grid)
	$(PY) -m harness.reports.report --quick $(REPORT_ARGS)
