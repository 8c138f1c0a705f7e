# Small helpers so that every library, test and benchmark is added the same way.

set(HNNSTEREO_WARNINGS -Wall -Wextra -Wpedantic -Wshadow -Wconversion -Wno-sign-conversion)

# hnnstereo_add_library(NAME SOURCES ... DEPS ...)
function(hnnstereo_add_library name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_library(${name} STATIC ${ARG_SOURCES})
  target_include_directories(${name} PUBLIC $<BUILD_INTERFACE:${PROJECT_SOURCE_DIR}>)
  target_compile_options(${name} PRIVATE ${HNNSTEREO_WARNINGS})
  target_link_libraries(${name} PUBLIC ${ARG_DEPS})
endfunction()

# hnnstereo_add_test(NAME SOURCES ... DEPS ... [LABELS ...])
function(hnnstereo_add_test name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS;LABELS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_compile_options(${name} PRIVATE ${HNNSTEREO_WARNINGS})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} GTest::gtest_main)
  target_compile_definitions(${name} PRIVATE
    HNNSTEREO_SOURCE_DIR="${PROJECT_SOURCE_DIR}"
    HNNSTEREO_SHARED_DIR="${PROJECT_SOURCE_DIR}/../shared"
    HNNSTEREO_BINARY="$<TARGET_FILE:hnnstereo>")
  add_test(NAME ${name} COMMAND ${name})
  set_tests_properties(${name} PROPERTIES
    ENVIRONMENT "POCL_CACHE_DIR=${PROJECT_BINARY_DIR}/pocl-cache;HNNSTEREO_KERNEL_CACHE=${PROJECT_BINARY_DIR}/kernel-cache"
    LABELS "${ARG_LABELS}" TIMEOUT 900)
endfunction()

# hnnstereo_extended_cases(TEST COMMAND FILTER): the GoogleTest cases of the CTest test TEST that
# the GTEST_FILTER pattern FILTER names (':'-separated) move to TEST_extended, a CTest entry
# running the same COMMAND with TEST's environment, labels and timeout plus the label `extended`
# (bash scripts/test.sh --extended; docs/testing.md); TEST runs the rest. For cases that assert
# on wall time or run long sweeps: the default suite stays fast and safe on a loaded machine.
# Call it after the test's own ENVIRONMENT is set.
function(hnnstereo_extended_cases test command filter)
  get_test_property(${test} ENVIRONMENT env)
  get_test_property(${test} LABELS labels)
  get_test_property(${test} TIMEOUT timeout)
  if(NOT env)
    set(env "")
  endif()
  if(NOT labels)
    set(labels "")
  endif()
  add_test(NAME ${test}_extended COMMAND ${command})
  set_tests_properties(${test}_extended PROPERTIES ENVIRONMENT "${env};GTEST_FILTER=${filter}"
    LABELS "${labels};extended")
  if(timeout)
    set_tests_properties(${test}_extended PROPERTIES TIMEOUT ${timeout})
  endif()
  set_tests_properties(${test} PROPERTIES ENVIRONMENT "${env};GTEST_FILTER=-${filter}")
endfunction()

# hnnstereo_add_benchmark(NAME SOURCES ... DEPS ...)
function(hnnstereo_add_benchmark name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_compile_options(${name} PRIVATE ${HNNSTEREO_WARNINGS})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} benchmark::benchmark)
  target_compile_definitions(${name} PRIVATE
    HNNSTEREO_SHARED_DIR="${PROJECT_SOURCE_DIR}/../shared")
endfunction()

# hnnstereo_enable_sanitizers("address,undefined" | "thread"): compile and link everything defined
# after this call with the sanitizers. UBSan findings abort (-fno-sanitize-recover) so that CTest
# sees them as failures instead of a line in the log nobody reads.
function(hnnstereo_enable_sanitizers list)
  string(REPLACE "," ";" requested "${list}")
  foreach(sanitizer ${requested})
    if(NOT sanitizer MATCHES "^(address|undefined|thread)$")
      message(FATAL_ERROR "HNNSTEREO_SANITIZE: unknown sanitizer '${sanitizer}' (address, undefined, thread)")
    endif()
  endforeach()
  if("thread" IN_LIST requested AND ("address" IN_LIST requested))
    message(FATAL_ERROR "HNNSTEREO_SANITIZE: thread cannot be combined with address")
  endif()
  # -O1 (after the build type's -O3, so it wins): the sanitizers' own advice, readable stacks, and
  # on this two-core machine about half the compile time of -O3 with instrumentation.
  set(flags -fsanitize=${list} -fno-omit-frame-pointer -g -O1)
  if("undefined" IN_LIST requested)
    list(APPEND flags -fno-sanitize-recover=undefined)
  endif()
  add_compile_options(${flags})
  add_link_options(-fsanitize=${list})
  message(STATUS "hnnstereo: sanitizers ${list}")
endfunction()
