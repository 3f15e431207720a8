# Mutation testing (mk/mutate.py): every small bug of mk/mutations.toml (a constant off by 1 %,
# swapped arguments, an off-by-one index, a dropped cosine, a sign) applied to a scratch copy of
# the library (build/mutate/src, built incrementally in build/mutate/shading, the fork relinked
# against it as build/mutate/bin/povray-brdf) or of the Python reference (build/mutate/py);
# unit tests first, then the mutation's fast pytest targets; stops at the first failure. Fails
# if any mutation is missed. Not part of `make test` (7.3 min for 43 mutations with a warm ccache
# on two busy cores; the first run also compiles the scratch library). MUTATE_ONLY="id ..." runs some.
MUTATE_ONLY ?=
.PHONY: mutate

mutate: all venv brdf-data ## Break the code on purpose (mk/mutations.toml) and check the tests catch every mutation: build/mutate/report.txt
	$(PY) mk/mutate.py $(if $(MUTATE_ONLY),--only $(MUTATE_ONLY))
