# Shoal: the two user-facing entry points.
#   make demo   install missing Debian packages, configure, build, run the main job
#   make test   the same set-up, then the whole test suite through CTest
# Everything else here is plumbing for those two.

BUILD_DIR ?= build
JOBS ?= $(shell nproc 2>/dev/null || echo 2)
CMAKE_FLAGS ?= -DCMAKE_BUILD_TYPE=Release

# Debian packages the build, the tests and the demo need.
DEB_PACKAGES := cmake g++ make pkg-config iproute2 procps time \
  liblcm-dev liblcm-bin libglib2.0-dev \
  libeigen3-dev libtomlplusplus-dev libcli11-dev libgtest-dev libbenchmark-dev \
  libsdp-dev libceres-dev libosmesa6-dev libstb-dev zlib1g-dev fonts-dejavu-core \
  nlohmann-json3-dev universal-ctags libsodium-dev python3
# make test also runs each libFuzzer target briefly (bench/fuzz.sh): clang and its runtime,
# about 45 MB to download. PACKAGES: what `deps` installs (make test adds these).
FUZZ_PACKAGES := clang libclang-rt-14-dev
# make test runs a sharded campaign on a single-node Slurm cluster it starts itself
# (tests/slurm/): Slurm's daemons and clients and the munge authentication daemon, about
# 8 MB to download; no daemon starts on install.
SLURM_PACKAGES := slurm-wlm munge
# make test decodes Shoal's logs through the Java classes lcm-spy uses (tests/java): a
# headless JDK (OpenJDK 17) and LCM's Java library, about 120 MB to download;
# SHOAL_REQUIRE_JAVA makes the configure fail rather than leave that test out.
JAVA_PACKAGES := default-jdk-headless liblcm-java
# python/shoal_log.py needs only the standard library; its DataFrame view (frames()) is
# tested with Debian's pandas, about 30 MB to download.
PYTHON_PACKAGES := python3-pandas
# make test starts processes through a real ssh (tests/netns/ssh_hosts_test.sh): OpenSSH's
# server and client; the test runs its own sshd with its own config, keys and port.
SSH_PACKAGES := openssh-server openssh-client
# make test counts the instructions a lockstep run's roles execute per tick at 5 and 64
# followers (tests/scale/, bench/scale_work.sh): valgrind's callgrind.
SCALE_PACKAGES := valgrind
PACKAGES = $(DEB_PACKAGES)
test: PACKAGES = $(DEB_PACKAGES) $(FUZZ_PACKAGES) $(SLURM_PACKAGES) $(JAVA_PACKAGES) \
  $(PYTHON_PACKAGES) $(SSH_PACKAGES) $(SCALE_PACKAGES)
test: CMAKE_FLAGS += -DSHOAL_REQUIRE_JAVA=ON
# Executions per fuzz target in make test (a few seconds each; bench/fuzz.sh 10000000 is
# the campaign of docs/benchmarks.md).
FUZZ_SHORT_RUNS ?= 50000

.PHONY: demo test test-long test-asan test-asan-ci test-tsan deps build configure clean

# shoal design exits 1 when the gains are not certified: for the paper's Example 2 that is
# the honest answer (Theorem 3 is only sufficient), so the demo says so instead of failing;
# any other status (2: bad input) stops the demo.
demo: build
	@echo "== shoal design: the paper's Example 2 gains, and gains it advises (--advise)"
	@echo "\$$ shoal design scenarios/paper_example2.toml --advise --write-scenario $(BUILD_DIR)/paper_example2_advised.toml"
	@$(BUILD_DIR)/tools/shoal design scenarios/paper_example2.toml --advise \
	  --write-scenario $(BUILD_DIR)/paper_example2_advised.toml; status=$$?; \
	if [ $$status -eq 1 ]; then \
	  echo "== exit status 1: the paper's gains are not certified (the verdict above says why);"; \
	  echo "   Theorem 3 is only sufficient: the simulations below run the advised and the paper's gains."; \
	elif [ $$status -ne 0 ]; then exit $$status; fi
	@echo "== shoal sim: the advised gains ($(BUILD_DIR)/paper_example2_advised.toml)"
	$(BUILD_DIR)/tools/shoal sim $(BUILD_DIR)/paper_example2_advised.toml --out $(BUILD_DIR)/paper_example2_advised_sim.lcmlog
	@echo "== shoal sim: the paper's Example 2 in one process"
	$(BUILD_DIR)/tools/shoal sim scenarios/paper_example2.toml --out $(BUILD_DIR)/paper_example2_sim.lcmlog
	@echo "== shoal run: the same as a lockstep SIL run (one process per vehicle, channel emulator, lcm-logger)"
	$(BUILD_DIR)/tools/shoal run scenarios/paper_example2.toml --mode lockstep --out $(BUILD_DIR)/paper_example2_sil.lcmlog
	$(BUILD_DIR)/tools/shoal compare $(BUILD_DIR)/paper_example2_sil.lcmlog $(BUILD_DIR)/paper_example2_sim.lcmlog
	@echo "== shoal analyze: the SIL run's log (CSV time series in $(BUILD_DIR)/paper_example2_csv)"
	$(BUILD_DIR)/tools/shoal analyze $(BUILD_DIR)/paper_example2_sil.lcmlog --csv $(BUILD_DIR)/paper_example2_csv
	@echo "== shoal render: its figures, drawn off-screen (OSMesa)"
	$(BUILD_DIR)/tools/shoal render $(BUILD_DIR)/paper_example2_sil.lcmlog --out $(BUILD_DIR)/paper_example2_figures
	@echo "== SIL log: $(BUILD_DIR)/paper_example2_sil.lcmlog (replay: lcm-logplayer $(BUILD_DIR)/paper_example2_sil.lcmlog)"
	@echo "== figures: $(BUILD_DIR)/paper_example2_figures/*.png"

test: build
	cd $(BUILD_DIR) && ctest --output-on-failure -j $(JOBS) -LE long
	bench/fuzz.sh $(FUZZ_SHORT_RUNS)

# Tests too long for the default pass (label long: the two-hour soak of docs/campaigns.md);
# CI runs them after make test.
test-long: build
	cd $(BUILD_DIR) && ctest --output-on-failure -L long

# Sanitizer builds (CMakePresets.json), each in its own build directory (build-asan,
# build-tsan): the whole suite under AddressSanitizer + UndefinedBehaviorSanitizer +
# LeakSanitizer, and the tests that start Shoal's LCM processes through shoal run (labels
# sil, replay; only their executables are built) under ThreadSanitizer. The processes
# they start are the instrumented builds too. SAN_CMAKE_FLAGS: extra configure flags
# (e.g. ccache as compiler launcher).
SAN_CMAKE_FLAGS ?=

test-asan: deps
	cmake --preset asan -DSHOAL_TEST_LABELS_LEFT_OUT= $(SAN_CMAKE_FLAGS)
	cmake --build --preset asan -j $(JOBS)
	ctest --preset asan -j $(JOBS)

# What CI runs under ASan+UBSan: every test except those that start a whole run of
# processes and check its timing or throughput (labels sil, replay), which a sanitizer's
# 2-5x slowdown breaks on two cores without any memory error (docs/benchmarks.md,
# "Sanitizers"), whose GoogleTest executables are not even built; a test that fails once is
# run again, since a sanitizer report fails it every time.
test-asan-ci: deps
	cmake --preset asan "-DSHOAL_TEST_LABELS_LEFT_OUT=sil;replay;long" $(SAN_CMAKE_FLAGS)
	cmake --build --preset asan -j $(JOBS)
	ctest --preset asan -j $(JOBS) -LE 'sil|replay|long' --repeat until-pass:2

test-tsan: deps
	cmake --preset tsan $(SAN_CMAKE_FLAGS)
	cmake --build --preset tsan -j $(JOBS) --target sil_test replay_test
	ctest --preset tsan -j $(JOBS) -L 'sil|replay'

# Installs the missing Debian packages; no daemon starts on install (policy-rc.d, unless the
# machine has its own): the tests start the sshd, munge and Slurm daemons they need themselves.
deps:
	@missing=""; \
	for p in $(PACKAGES); do \
	  dpkg-query -W -f='$${Status}' $$p 2>/dev/null | grep -q "install ok installed" || missing="$$missing $$p"; \
	done; \
	if [ -z "$$missing" ]; then exit 0; fi; \
	if [ "$$(id -u)" = 0 ]; then \
	  echo "== installing missing Debian packages:$$missing"; \
	  export DEBIAN_FRONTEND=noninteractive; \
	  if [ ! -e /usr/sbin/policy-rc.d ]; then \
	    printf '#!/bin/sh\nexit 101\n' > /usr/sbin/policy-rc.d && chmod 755 /usr/sbin/policy-rc.d; \
	    trap 'rm -f /usr/sbin/policy-rc.d' EXIT; \
	  fi; \
	  apt-get update -q && apt-get install -y -q --no-install-recommends $$missing; \
	else \
	  echo "Missing Debian packages:$$missing"; \
	  echo "Install them with:"; \
	  echo "  sudo apt-get update && sudo apt-get install -y$$missing"; \
	  exit 1; \
	fi

configure: deps
	cmake -S . -B $(BUILD_DIR) $(CMAKE_FLAGS)

build: configure
	cmake --build $(BUILD_DIR) -j $(JOBS)

clean:
	rm -rf $(BUILD_DIR) build-asan build-tsan
