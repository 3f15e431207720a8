# Side-by-side material studies: harness/reports/study.py renders every material of a study file
# (TOML) on every shape under every light into a contact sheet (out/study/<name>/sheet.png,
# index.html: trace time and memory per image, BRDF polar plots of the table materials).
# STUDY=path/to.toml picks the study; SCHEDULER=tcp://host:8786 sends the renders to an
# existing Dask distributed scheduler instead of local parallel jobs (JOBS at a time).
STUDY     ?= studies/example.toml
SCHEDULER ?=
.PHONY: study

study: all venv brdf-data ## Render a material study (STUDY=studies/example.toml) into a contact sheet: out/study/NAME/sheet.png, index.html
	$(PY) -m harness.reports.study $(STUDY) --jobs $(JOBS) $(if $(SCHEDULER),--scheduler $(SCHEDULER))
