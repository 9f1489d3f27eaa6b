#!/usr/bin/env bash
# ASan + UBSan run of the fast test suites (issue 14 item 4).
#
# Configures ./build-sanitize with -DAOSR_SANITIZE=ON (ASan + UBSan, UBSan findings abort), -O1 -g1 and
# without NDEBUG, so Eigen's range assertions stay on; builds only the test executables it covers and runs
# them with ctest. Any sanitizer report fails its test, and so this script.
#
# What it covers (COVERED below): the `unit`, `errors` and `stability` test executables of every layer,
# the cli suite included (it runs the sanitized aosr executable on whole scenes; SANITIZE_CLI=0 leaves it
# out for a quicker local run), plus every `fuzz_*` target when fuzz/ defines some (label `fuzz`) and the
# randomised end-to-end campaign `aosr_campaign` (label `campaign`, CAMPAIGN_RUNS runs). Left out to fit
# CI's budget (instrumented tests took ~3x their Release CPU when GCC built them): the `physics` and `slow` suites (long
# statistical oracles) and the long tests of scripts/sanitize_skip.txt (each >= 19 s here, its code run by
# shorter tests of this stage). The measured time is in docs/development.md.
#
# Usage: scripts/sanitize.sh [extra ctest arguments, e.g. -R Fft]
# Environment: SANITIZE_CLI=0 (leave out the cli suite), SANITIZE_SKIP=0 (also run scripts/sanitize_skip.txt), JOBS (default nproc), BUILD_DIR (default
# build-sanitize), FUZZ_SECONDS (default 20), CAMPAIGN_RUNS (default 40), CAMPAIGN_SEED (default 2), SANITIZE_CXX_FLAGS (default "-O1 -g1"),
# SANITIZE_CXX (default clang++-14; g++ for GCC).
set -euo pipefail
cd "$(dirname "$0")/.."

build_dir=${BUILD_DIR:-build-sanitize}
jobs=${JOBS:-$(nproc 2>/dev/null || echo 2)}

# The test executables the run covers: the unit, errors and stability suites of every layer
# (solvers_unit_tests: 111 tests, ~70 s on 2 cores under the sanitizers; the cli suite and the sanitized
# executable it runs: 62 tests, ~4 min).
COVERED=(core_unit_tests core_errors_tests io_unit_tests io_errors_tests optics_unit_tests optics_errors_tests
         ao_unit_tests ao_errors_tests scene_unit_tests scene_errors_tests solvers_unit_tests
         solvers_stability_tests solvers_errors_tests design_unit_tests design_errors_tests calib_unit_tests
         calib_errors_tests)
if [ "${SANITIZE_CLI:-1}" = 1 ]; then COVERED+=(cli_unit_tests aosr_cli); fi
COVERED_LABELS=(unit errors stability)
# Wall-time cap of each fuzz target's mutation phase here (fuzz/CMakeLists.txt AOSR_FUZZ_MAX_SECONDS; the
# corpus and regressions are always replayed in full): 8 targets x 20 s on 2 cores is under 2 minutes.
fuzz_seconds=${FUZZ_SECONDS:-20}
# Runs of the end-to-end campaign (fuzz/campaign.cpp; 150 runs of seed 1 in the Release suite). Each run simulates,
# reconstructs (twice: the rerun's bytes are compared) and evaluates a small scene; under ASan + UBSan a run takes
# ~3 s of one core (CI: 100 runs in 312 s). Seed 2 here: draws the Release suite does not make.
campaign_runs=${CAMPAIGN_RUNS:-40}
campaign_seed=${CAMPAIGN_SEED:-2}

# -O1: ASan's recommended level (2-3x slowdown instead of ~10x at -O0). -g1: line tables only, so reports
# still give file:line for every frame, at ~25 % less compile time than -g (measured on src/ao and
# src/optics files; the sanitizer build is most of this script's time). The build type is Debug only to keep
# NDEBUG undefined (Eigen's eigen_assert checks every coefficient index); its flags are replaced, so
# nothing else of Debug applies. SANITIZE_CXX_FLAGS overrides them (e.g. "-O1 -g" to debug a finding).
cxx_flags=${SANITIZE_CXX_FLAGS:-"-O1 -g1"}
# The compiler: Debian's clang 14 (installed here with its sanitizer runtimes when missing), because this build is
# most of CI's time and clang compiles it in about three quarters of GCC's CPU time with the same flags (test
# suites 0.69x, libraries 0.79-0.83x: docs/development.md, "Sanitizers"). Its -fsanitize=undefined checks a
# superset of GCC's (float-cast-overflow and function as well). SANITIZE_CXX=g++ builds with GCC instead.
cxx=${SANITIZE_CXX:-clang++-14}
case $cxx in clang++*) scripts/install_packages.sh clang-14 libclang-rt-14-dev ;; esac
cxx_path=$(command -v "$cxx") || { echo "sanitize: compiler $cxx not found" >&2; exit 1; }
# A build folder configured with another compiler is configured afresh (CMake cannot switch compilers in place).
if [ -f "$build_dir/CMakeCache.txt" ] && ! grep -qx "CMAKE_CXX_COMPILER:[A-Z]*=$cxx_path" "$build_dir/CMakeCache.txt"; then
  echo "sanitize: $build_dir was configured with another compiler; configuring it afresh for $cxx"
  rm -rf "$build_dir/CMakeCache.txt" "$build_dir/CMakeFiles"
fi
generator=()
if [ ! -f "$build_dir/CMakeCache.txt" ] && command -v ninja > /dev/null; then generator=(-G Ninja); fi
cmake -S . -B "$build_dir" "${generator[@]}" -DCMAKE_CXX_COMPILER="$cxx_path" -DAOSR_SANITIZE=ON -DAOSR_BUILD_BENCH=OFF -DAOSR_BUILD_TESTS=ON \
  -DCMAKE_BUILD_TYPE=Debug -DCMAKE_CXX_FLAGS_DEBUG="$cxx_flags" \
  -DAOSR_FUZZ_MAX_SECONDS="$fuzz_seconds" -DAOSR_CAMPAIGN_RUNS="$campaign_runs" -DAOSR_CAMPAIGN_SEED="$campaign_seed" > "$build_dir.configure.log" 2>&1 ||
  { cat "$build_dir.configure.log"; exit 1; }
rm -f "$build_dir.configure.log"

# Targets: the covered executables that exist, plus the fuzz targets and the campaign when fuzz/ is present
# and enabled.
if [ -f "$build_dir/build.ninja" ]; then
  all_targets=$(ninja -C "$build_dir" -t targets all | sed -n 's/^\([A-Za-z0-9_]*\): phony$/\1/p')
else
  all_targets=$(cmake --build "$build_dir" --target help | sed -n 's/^\.\.\. \([^ ]*\).*/\1/p')
fi
targets=()
for t in "${COVERED[@]}"; do
  if grep -qx "$t" <<< "$all_targets"; then targets+=("$t"); fi
done
labels=$(IFS='|'; echo "${COVERED_LABELS[*]}")
if fuzz_targets=$(grep -x 'fuzz_.*' <<< "$all_targets"); then
  mapfile -t -O "${#targets[@]}" targets <<< "$fuzz_targets"
  labels="$labels|fuzz"
fi
if grep -qx aosr_campaign <<< "$all_targets"; then
  targets+=(aosr_campaign)
  labels="$labels|campaign"
fi
echo "sanitize: building ${targets[*]}"
cmake --build "$build_dir" -j"$jobs" --target "${targets[@]}"

# Sanitizer settings. ASan: report leaks at exit (LeakSanitizer), abort with a stack on the first error;
# scripts/lsan.supp lists the third-party one-time allocations that are not our leaks, each with its reason.
# UBSan: print the stack and stop at the first finding (the build also passes -fno-sanitize-recover).
# fast_unwind_on_malloc=1 (ASan's default, stated): allocation stacks by frame pointers (the build keeps them,
# -fno-omit-frame-pointer). The full DWARF unwinder on every allocation made the stage's tests 3-4x slower
# (optics_unit_tests 135 -> 31 s, scene_unit_tests 334 -> 105 s here, stop 40); only fuzz_image needs it, for the
# leak suppression that must see OpenImageIO's frame behind libstdc++'s, and fuzz/CMakeLists.txt sets it for that
# test alone.
# intercept_tls_get_addr=0: GCC 12's runtime (like GCC <= 13 and LLVM <= 16) intercepts __tls_get_addr and takes a
# dynamic TLS block whose start lies 16 bytes into a page for one with a pre-2.25 glibc header, reading the two
# words before it as an address and a length; LeakSanitizer's stop-the-world tracer then dereferences them and
# dies at exit ("Tracer caught signal 11", status 134) after the test itself has passed. Here the dynamic TLS is
# OpenImageIO's, loaded with dlopen by the PNG/TIFF plugin: CI's run at 4d61250 lost TradeoffCliTest to it, and
# after the allocator tuning it happened on every run of `aosr tradeoff` here. Without the interception LSan does
# not scan dlopen'ed libraries' thread-local blocks; it still finds leaks (checked on a deliberate one), and the
# whole sanitizer stage reports none.
export ASAN_OPTIONS="intercept_tls_get_addr=0:fast_unwind_on_malloc=1:detect_leaks=1:halt_on_error=1:abort_on_error=1:detect_stack_use_after_return=1:strict_string_checks=1:check_initialization_order=1:detect_invalid_pointer_pairs=0"
export LSAN_OPTIONS="suppressions=$PWD/scripts/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"

# gtest_discover_tests leaves a *_NOT_BUILT placeholder for every executable of the project not built
# here (physics, slow, cli, ...): exclude them; the labels select what was built. (No test asserts wall time.)
# scripts/sanitize_skip.txt lists the long tests left out here, with the rule and each one's measured time
# (SANITIZE_SKIP=0 runs them too).
exclude='_NOT_BUILT$'
if [ "${SANITIZE_SKIP:-1}" = 1 ]; then
  mapfile -t skip_names < <(sed -e 's/#.*//' -e 's/[[:space:]]//g' -e '/^$/d' scripts/sanitize_skip.txt)
  if [ "${#skip_names[@]}" -gt 0 ]; then
    exclude="$exclude|^($(IFS='|'; echo "${skip_names[*]//./\\.}"))\$"
    echo "sanitize: leaving out ${#skip_names[@]} long tests (scripts/sanitize_skip.txt)"
  fi
fi
ctest --test-dir "$build_dir" -L "^($labels)\$" -E "$exclude" --output-on-failure -j"$jobs" "$@"
