# LIGHTSTAGE_FUZZ: a separate build directory, configured with clang++, where the
# libraries and the tests named in LIGHTSTAGE_SANITIZE_TESTS are built under AddressSanitizer and
# UndefinedBehaviorSanitizer with libFuzzer's coverage, and fuzz/ holds one libFuzzer target per
# parser. scripts/fuzz.sh configures, builds and runs it; the normal build is untouched.
if(NOT CMAKE_CXX_COMPILER_ID STREQUAL "Clang")
  message(FATAL_ERROR "LIGHTSTAGE_FUZZ needs clang++ (libFuzzer is clang's): configure a separate "
                      "build directory with -DCMAKE_CXX_COMPILER=clang++ (scripts/fuzz.sh does)")
endif()
if(LIGHTSTAGE_WERROR)
  message(FATAL_ERROR "LIGHTSTAGE_FUZZ: LIGHTSTAGE_WERROR is for the GCC build; leave it OFF")
endif()

# Every test binary still compiles (other targets link them), but only these run under ctest
# (label "sanitize"): the parser and session tests, cheap enough under the sanitizers for CI.
set(LIGHTSTAGE_SANITIZE_TESTS lightstage_test CACHE STRING
    "Test executables built and registered (label sanitize) in the LIGHTSTAGE_FUZZ build")
# Tests that run the CLI run this one (the CLI is all of lightstage: not built here).
set(LIGHTSTAGE_FUZZ_CLI "${PROJECT_SOURCE_DIR}/build/app/cli/lightstage" CACHE FILEPATH
    "The lightstage executable the sanitized tests run (the normal build's)")

# -O1 without NDEBUG: assert() and Eigen's bounds checks stay on; line tables (cheaper than -g)
# give every frame of a report its file and line. UB is fatal (no recovery), so a test or fuzz run
# that hits it fails instead of printing and going on. _GLIBCXX_ASSERTIONS checks every
# std::vector/string index: AddressSanitizer alone misses an index far enough past the end to
# land in another live block.
set(CMAKE_CXX_FLAGS_RELEASE "-O1 -gline-tables-only")
set(LIGHTSTAGE_SANITIZE_FLAGS -fsanitize=address,undefined -fno-sanitize-recover=undefined
    -fno-omit-frame-pointer)
add_compile_options(${LIGHTSTAGE_SANITIZE_FLAGS} -fsanitize=fuzzer-no-link -D_GLIBCXX_ASSERTIONS)
add_link_options(${LIGHTSTAGE_SANITIZE_FLAGS})
