# How aosr is compiled quickly (issue 35; measurements and their commands in bench/results/build.md). None of this
# changes what is computed: the same sources, flags and optimisation level; only how many times headers are parsed,
# which linker runs and whether an unchanged file is compiled again.
#
#  * ccache, when installed and no launcher is set: a file compiled before with the same flags is not compiled
#    again (rebuilds, a second build folder, another worktree of the checkout). Precompiled headers need ccache's
#    pch_defines and time_macros sloppiness and GCC's -fpch-preprocess (ccache's manual, "Precompiled headers").
#    Its depend mode: a miss (every file of a first build, and of CI's) costs no extra preprocessor run, which
#    was 0.3-0.8 s per unity batch; the include list comes from the compiler's own -MD file, which Ninja asks for.
#  * mold (else lld), when installed: linking the ~40 executables and the Python module is a large share of an
#    incremental build; GNU ld takes seconds per test executable, mold a fraction of one.
#  * One precompiled header (the standard library, Eigen, JSON, GoogleTest) shared by all test executables
#    (REUSE_FROM), built once.
#  * Unity builds (aosr_unity) of the libraries, the engine, the Python module and the test executables: a few
#    files compiled as one (CMake includes the sources by path, so a compile error, diagnostics and __FILE__ still
#    name the file). The libraries in batches of 6, so that touching one numerical file recompiles a few; each
#    test executable as one translation unit, because the test files instantiate the same GoogleTest, Eigen and
#    JSON templates and that is most of their compile: 0.80x the CPU of batches of 6 with GCC and with clang's
#    sanitizer build (bench/results/build.md, "Stop 59"). Touching a test file recompiles its whole executable
#    (solvers_unit_tests: ~110 s); -DAOSR_UNITY_BATCH_TESTS=6 gives the smaller batches while editing tests.
#
# AOSR_FAST_BUILD=OFF turns the precompiled headers and unity builds off (e.g. to check that every file includes
# what it uses); ccache and the linker follow what is installed (CMAKE_CXX_COMPILER_LAUNCHER and
# AOSR_LINKER override them).
option(AOSR_FAST_BUILD "Precompiled headers and unity builds of the test suites (bench/results/build.md)" ON)
set(AOSR_UNITY_BATCH 6 CACHE STRING "Library, engine and module files compiled together in one unity translation unit")
set(AOSR_UNITY_BATCH_TESTS 0 CACHE STRING "Test files compiled together in one unity translation unit (0: all of an executable's)")

if(NOT CMAKE_CXX_COMPILER_LAUNCHER AND NOT DEFINED ENV{CMAKE_CXX_COMPILER_LAUNCHER})
  find_program(AOSR_CCACHE ccache)
  if(AOSR_CCACHE)
    set(CMAKE_CXX_COMPILER_LAUNCHER ${CMAKE_COMMAND} -E env
        "CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime" CCACHE_DEPEND=1
        ${AOSR_CCACHE})
    # ccache's preprocessor mode sees a precompiled header only through -fpch-preprocess (no effect without -E).
    if(AOSR_FAST_BUILD AND CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
      add_compile_options(-fpch-preprocess)
    endif()
    message(STATUS "aosr: compiling through ccache (${AOSR_CCACHE})")
  endif()
endif()

set(AOSR_LINKER "" CACHE STRING "Linker for -fuse-ld= (mold, lld, bfd, gold); empty: mold, else lld, else the default")
if(AOSR_LINKER STREQUAL "")
  find_program(_aosr_mold mold)
  find_program(_aosr_lld ld.lld)
  if(_aosr_mold)
    set(_aosr_ld mold)
  elseif(_aosr_lld)
    set(_aosr_ld lld)
  endif()
else()
  set(_aosr_ld ${AOSR_LINKER})
endif()
if(_aosr_ld)
  include(CheckLinkerFlag)
  check_linker_flag(CXX "-fuse-ld=${_aosr_ld}" AOSR_HAVE_LINKER_${_aosr_ld})
  if(AOSR_HAVE_LINKER_${_aosr_ld})
    add_link_options(-fuse-ld=${_aosr_ld})
    message(STATUS "aosr: linking with ${_aosr_ld}")
  endif()
endif()

# The headers worth precompiling for the test executables, which share one precompiled header (tests/CMakeLists.txt):
# built once, it replaces the parse of Eigen, JSON and GoogleTest in every one of ~90 unity batches. The libraries,
# the engine and the Python module have none: with two to six unity batches a target, building a target's own
# header (5-13 s each) cost more than it saved. Measured (bench/results/build.md): command 1's build 347 s wall,
# 656 compiler CPU-s with them; 300 s, 547 CPU-s without.
set(AOSR_PCH_TEST_HEADERS <algorithm> <cmath> <complex> <functional> <memory> <string> <vector> <Eigen/Core>
    <Eigen/Dense> <nlohmann/json.hpp> <gtest/gtest.h> <gmock/gmock.h>)

# aosr_unity(TARGET [BATCH]): TARGET's sources compiled in unity batches of BATCH (default AOSR_UNITY_BATCH)
# files. A file with its own compile options is compiled alone (SKIP_UNITY_BUILD_INCLUSION where it is set).
function(aosr_unity target)
  set(batch ${AOSR_UNITY_BATCH})
  if(ARGC GREATER 1)
    set(batch ${ARGV1})
  endif()
  if(AOSR_FAST_BUILD)
    set_target_properties(${target} PROPERTIES UNITY_BUILD ON UNITY_BUILD_MODE BATCH UNITY_BUILD_BATCH_SIZE ${batch})
  endif()
endfunction()

# aosr_glue_optimisation(TARGET): -O2 instead of Release's -O3 for code that parses, prints and binds (the CLI's
# commands, the Python bindings) or checks (the test executables), where -O3's extra vectorisation and unrolling buy
# nothing: the numerical work they call is in the libraries, compiled at -O3. It is 15 % of these targets' compile
# time (bench/results/build.md, stops 57 and 58). The arithmetic is IEEE either way (no -ffast-math, no FMA
# contraction on x86-64's baseline), so the results are the same bits. Not lower: an executable's own copies of the
# header templates (Eigen's kernels) are the ones the linker keeps, so the libraries run them inside that executable
# (stop 50: test code at -O0 slowed the sanitizer stage's tests by a quarter); at -O2 those kernels run as fast.
function(aosr_glue_optimisation target)
  target_compile_options(${target} PRIVATE $<$<CONFIG:Release>:-O2>)
endfunction()
