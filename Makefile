# Entry points of the project; each target first brings .venv up to date
# (scripts/setup_env.sh is a no-op taking about a second when nothing changed).
.PHONY: env test demo bench

PYTHON := .venv/bin/python

env:
	bash scripts/setup_env.sh

# pytest's exit code is passed through (5, "no tests collected", counts as failure);
# -rR names every DDS process test that needed a rerun (see test/conftest.py).
test: env
	$(PYTHON) -m pytest -q -rR test

# test-compat (issue #14's name): the suite's library tests (no DDS processes) with the oldest supported libraries, those of
# Ubuntu 24.04 + ROS 2 Jazzy from apt: numpy 1.26.4, OpenCV 4.6.0, SciPy 1.11.4, numba
# 0.58.1, pandas 2.1.4 (requirements/oldest.txt, in .venv-oldest; scripts/test_oldest.sh).
.PHONY: test-compat test-oldest
test-compat: env
	bash scripts/test_oldest.sh -q -rR test --ignore=test/ros

# The former name of test-compat (.ci/run calls it).
test-oldest: test-compat

demo: env
	.venv/bin/mk_tracker demo

# Runs every benchmark script in turn; each prints its figures and writes its report
# into docs/.
bench: env
	@set -e; for script in benchmarks/*.py; do \
		echo "== $$script"; $(PYTHON) "$$script"; \
	done

# Mutation testing of the five core math modules with mutmut, each against its own tests
# (a few minutes per module; a maintainers' habit, not part of make test).  Results and
# the equivalent mutants: docs/mutation.md.  One module: bash scripts/mutation.sh boxes
.PHONY: mutation
mutation: env
	bash scripts/mutation.sh
