# Helpers shared by every area of the tree.

# Warnings as errors on our own targets only (never on third-party headers, which are included as SYSTEM).
function(cw_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wno-sign-conversion
                                           -Wnon-virtual-dtor -Wold-style-cast -Woverloaded-virtual)
  if(CW_WERROR)
    target_compile_options(${target} PRIVATE -Werror)
  endif()
endfunction()

# cw_library(<name> DIR <area> DEPS <targets...> [PRIVATE_DEPS ...] [SYSTEM_INCLUDES ...] [DEFINES ...])
# An area's library: headers in <area>/include, sources globbed from <area>/src (CONFIGURE_DEPENDS, so adding a file
# is picked up by the next build without editing CMake).
function(cw_library name)
  cmake_parse_arguments(ARG "" "DIR" "DEPS;PRIVATE_DEPS;SYSTEM_INCLUDES;DEFINES" ${ARGN})
  file(GLOB_RECURSE srcs CONFIGURE_DEPENDS ${ARG_DIR}/src/*.cpp)
  if(srcs)
    add_library(${name} STATIC ${srcs})
    target_include_directories(${name} PUBLIC ${ARG_DIR}/include PRIVATE ${ARG_DIR}/src)
    target_link_libraries(${name} PUBLIC ${ARG_DEPS} PRIVATE ${ARG_PRIVATE_DEPS})
    target_include_directories(${name} SYSTEM PUBLIC ${ARG_SYSTEM_INCLUDES})
    target_compile_definitions(${name} PUBLIC ${ARG_DEFINES})
    cw_warnings(${name})
  else()
    add_library(${name} INTERFACE)
    target_include_directories(${name} INTERFACE ${ARG_DIR}/include)
    target_link_libraries(${name} INTERFACE ${ARG_DEPS})
    target_include_directories(${name} SYSTEM INTERFACE ${ARG_SYSTEM_INCLUDES})
    target_compile_definitions(${name} INTERFACE ${ARG_DEFINES})
  endif()
endfunction()

# cw_test_suite(<name> DIR <tests/area> DEPS <targets...> [EXCLUDE <subdirs...>] [FILES <files...>]
#               [EXCLUDE_FILES <files...>] [COST <seconds>])
# One GoogleTest executable per area, one *_test.cpp file per unit under test. FILES (names in DIR) makes a suite of
# just those files, EXCLUDE_FILES leaves them out: an area split so that a sanitizer leg compiles only the tests it
# runs (.ci/run). COST: the suite's mean seconds per
# test, for `ctest -j` to start the slow suites first in a build directory that has no timings of its own yet (CI's
# clean clone; afterwards ctest uses the timings it recorded in Testing/Temporary/CTestCostData.txt).
function(cw_test_suite name)
  cmake_parse_arguments(ARG "" "DIR;COST" "DEPS;EXCLUDE;FILES;EXCLUDE_FILES" ${ARGN})
  if(ARG_FILES)
    list(TRANSFORM ARG_FILES PREPEND ${ARG_DIR}/ OUTPUT_VARIABLE srcs)
  else()
    file(GLOB_RECURSE srcs CONFIGURE_DEPENDS ${ARG_DIR}/*_test.cpp)
  endif()
  foreach(sub ${ARG_EXCLUDE})  # subdirectories that are suites of their own
    list(FILTER srcs EXCLUDE REGEX "^${ARG_DIR}/${sub}/")
  endforeach()
  foreach(file ${ARG_EXCLUDE_FILES})
    list(REMOVE_ITEM srcs ${ARG_DIR}/${file})
  endforeach()
  if(NOT srcs)
    return()
  endif()
  add_executable(${name} ${srcs})
  target_include_directories(${name} PRIVATE ${CMAKE_SOURCE_DIR}/tests)
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest GTest::gmock GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE CW_SOURCE_DIR="${CMAKE_SOURCE_DIR}"
                                             CW_TWIN_EXE="$<TARGET_FILE:twin>")
  cw_warnings(${name})
  # Test code is optimised less than the libraries it tests: two thirds of a full build's compile time is the test
  # files (GoogleTest's macros expand to large functions that -O2 works hard on), and at -O1 a test file compiles in
  # about three quarters of the time (tests/tools/run_cli_test.cpp: 14.3 s against 18.9 s, one core) while the suites
  # run as fast (the work is in the libraries, still -O2). Builds that ask for no optimisation keep theirs.
  # With AddressSanitizer the test code is not optimised at all: the sanitizers are there for the libraries (still
  # optimised as configured, -O1 in CI's legs), the test files stay fully instrumented, and an instrumented test file
  # compiles in 18-43 % less CPU time at -O0 (ASan+UBSan: tests/drivers/driver_core_test.cpp 10.8 s against 18.8 s,
  # tests/controller/runtime/robot_control_test.cpp 37.4 s against 45.4 s). With TSan -O0 gains little (driver_core_test
  # 9.0 s against 9.9 s) and the test files keep -O1.
  if(CW_SANITIZE MATCHES "address")
    set(test_opt -O0)
  else()
    set(test_opt -O1)
  endif()
  target_compile_options(${name} PRIVATE $<$<CONFIG:RelWithDebInfo,Release>:${test_opt}>)
  if(NOT ARG_COST)
    set(ARG_COST 0)
  endif()
  gtest_discover_tests(${name} DISCOVERY_TIMEOUT 60 PROPERTIES ENVIRONMENT "MUJOCO_GL=osmesa" COST ${ARG_COST})
endfunction()
