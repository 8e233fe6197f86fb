# Two entry points for a fresh clone: `make demo` (the main job) and `make test`.
# Both create .venv from pyproject.toml on first use.
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test fuzz bench lint clean native ros

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# The compiled tier (mypyc): a few minutes, for ~1.2-1.3x faster runs; rebuilt only when a
# board source changed. Asked for, never a step of demo or test, so that a fresh clone flies
# within a minute or two. Without a C compiler the build fails and `hil` runs the pure modules:
# same results, slower.
native: $(STAMP)
	$(VENV)/bin/hil native build --if-needed || echo "hil: compiled tier not built; running pure Python"

# Flies on the compiled tier if `make native` built it, else on the pure modules (it says which).
demo: $(STAMP)
	$(VENV)/bin/hil run

# Two passes: everything but the wall-clock-paced tests, spread over the cores (pytest-xdist),
# then the paced ones alone, so that no other test takes the CPU they need to keep pace.
# The tier's equivalence test builds a quick tier of its own when `make native` has not, on one
# worker while the other runs the rest (tests/hil/test_native.py). --dist loadfile keeps a file
# on one worker (a flight its tests share is flown once, nobody waits for it) and the slow
# tests start first (tests/conftest.py), so the short ones even out the end.
test: $(STAMP) ros
	$(PY) -m pytest -q -n auto --dist loadfile -m "not paced"
	$(PY) -m pytest -q -m paced

# ROS 1 from Debian (the ROS edge, hil/ros/, and its tests): installed with apt-get only when
# `roscore` is missing, which needs root (.ci/run runs as root); rospy is pure Python in
# /usr/lib/python3/dist-packages, which hil.ros appends to the venv's sys.path.
ROS_DEBS := ros-core python3-rospy python3-rostopic python3-std-msgs python3-sensor-msgs \
            python3-geometry-msgs python3-nav-msgs python3-rosgraph-msgs
ros:
	@command -v roscore >/dev/null 2>&1 || { \
	  echo "make ros: roscore not found; installing Debian's ROS 1 (apt-get, needs root)"; \
	  apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y \
	    --no-install-recommends $(ROS_DEBS); }

# The long fuzz run: every fuzz target (tests/fuzzing.py) with FUZZ_SCALE times the budget it
# has in `make test`, in one process so that hypothesis prints per target how many inputs it
# tried and how long that took (about fifty minutes at the default scale).
FUZZ_SCALE ?= 50
fuzz: $(STAMP)
	HIL_FUZZ_SCALE=$(FUZZ_SCALE) $(PY) -m pytest -q -m fuzz -p no:cacheprovider --hypothesis-show-statistics

bench: $(STAMP)
	$(VENV)/bin/hil bench

clean:
	rm -rf $(VENV) build *.egg-info .native
