# Golden-image regression renders: harness/reports/regress.py over scenes/regress/ (regress.toml lists
# the scenes, golden/NAME.exr + golden/NAME.toml are each scene's golden and tolerance).
# REGRESS_ONLY="name ..." limits either target to some scenes.
.PHONY: regress regress-bless

regress: all venv brdf-data ## Render scenes/regress with the fork and compare with the goldens (out/regress/index.html); fails on any regression
	$(PY) -m harness.reports.regress $(if $(REGRESS_ONLY),--only $(REGRESS_ONLY))

regress-bless: all venv brdf-data ## Re-render scenes/regress and rewrite the goldens deliberately; the report says what changed
	$(PY) -m harness.reports.regress --bless $(if $(REGRESS_ONLY),--only $(REGRESS_ONLY))
