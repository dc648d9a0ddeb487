# One helper per kind of target so every folder builds the same way.
# -Wno-restrict: GCC 12 reports false positives inside std::string (GCC bug 105329).
set(LIGHTSTAGE_WARNINGS -Wall -Wextra -Wpedantic -Wno-missing-field-initializers)
if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
  list(APPEND LIGHTSTAGE_WARNINGS -Wno-restrict)  # clang (LIGHTSTAGE_FUZZ) has no such warning.
endif()
if(LIGHTSTAGE_WERROR)
  list(APPEND LIGHTSTAGE_WARNINGS -Werror)
endif()

# lightstage_library(NAME SOURCES ... PUBLIC_LINKS ... PRIVATE_LINKS ...)
function(lightstage_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;PUBLIC_LINKS;PRIVATE_LINKS" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC ${PROJECT_SOURCE_DIR})
  target_compile_options(${name} PRIVATE ${LIGHTSTAGE_WARNINGS})
  target_link_libraries(${name} PUBLIC ${ARG_PUBLIC_LINKS} PRIVATE ${ARG_PRIVATE_LINKS})
  if(LIGHTSTAGE_WITH_PYTHON)
    # Linked into the Python module too (a shared object). No semantic interposition: calls within
    # a library are optimised as in the executables' position-independent code.
    set_target_properties(${name} PROPERTIES POSITION_INDEPENDENT_CODE ON)
    if(CMAKE_CXX_COMPILER_ID STREQUAL "GNU")
      target_compile_options(${name} PRIVATE -fno-semantic-interposition)
    endif()
  endif()
endfunction()

# lightstage_test(NAME SOURCES ... LINKS ... [LABELS ...]): one GoogleTest binary, registered with CTest.
function(lightstage_test name)
  cmake_parse_arguments(ARG "" "TIMEOUT" "SOURCES;LINKS;LABELS" ${ARGN})
  # The sanitizer build (cmake/Fuzzing.cmake) builds and runs only the tests it names.
  set(exclude "")
  if(LIGHTSTAGE_FUZZ)
    if(NOT name IN_LIST LIGHTSTAGE_SANITIZE_TESTS)
      set(exclude EXCLUDE_FROM_ALL)
    endif()
    list(APPEND ARG_LABELS sanitize)
  endif()
  add_executable(${name} ${exclude} ${ARG_SOURCES})
  target_compile_options(${name} PRIVATE ${LIGHTSTAGE_WARNINGS})
  target_link_libraries(${name} PRIVATE ${ARG_LINKS} lightstage_test_support GTest::gtest_main GTest::gmock)
  if(exclude)
    return()
  endif()
  if(NOT ARG_TIMEOUT)
    set(ARG_TIMEOUT 600)
  endif()
  gtest_discover_tests(${name}
    WORKING_DIRECTORY ${PROJECT_SOURCE_DIR}
    PROPERTIES TIMEOUT ${ARG_TIMEOUT} LABELS "${ARG_LABELS}"
    DISCOVERY_TIMEOUT 60)
endfunction()

function(lightstage_benchmark name)
  cmake_parse_arguments(ARG "" "" "SOURCES;LINKS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_compile_options(${name} PRIVATE ${LIGHTSTAGE_WARNINGS})
  target_link_libraries(${name} PRIVATE ${ARG_LINKS} benchmark::benchmark)
endfunction()
