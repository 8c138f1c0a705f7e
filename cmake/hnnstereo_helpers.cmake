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

# hnnstereo_add_benchmark(NAME SOURCES ... DEPS ...)
function(hnnstereo_add_benchmark name)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPS" ${ARGN})
  add_executable(${name} ${ARG_SOURCES})
  target_compile_options(${name} PRIVATE ${HNNSTEREO_WARNINGS})
  target_link_libraries(${name} PRIVATE ${ARG_DEPS} benchmark::benchmark)
  target_compile_definitions(${name} PRIVATE
    HNNSTEREO_SHARED_DIR="${PROJECT_SOURCE_DIR}/../shared")
endfunction()
