# The library contract end to end: install the build into a scratch prefix, configure and build
# examples/cpp against it (the package alone, as a user outside the tree would), run it on the
# vendored Teddy pair and check it finds the CLI's match count.
# cmake -DBUILD_DIR=... -DSOURCE_DIR=... -DCLI=... [-DLAUNCHER=ccache] -P install_example_test.cmake
set(prefix ${BUILD_DIR}/api-test/prefix)
set(example_build ${BUILD_DIR}/api-test/example-build)
set(teddy ${SOURCE_DIR}/tests/data/middlebury2003_teddy)
file(REMOVE_RECURSE ${prefix})

function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "failed (${code}): ${ARGN}\n${out}\n${err}")
  endif()
  set(run_output "${out}" PARENT_SCOPE)
endfunction()

string(TIMESTAMP start "%s")
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
string(TIMESTAMP installed "%s")
foreach(file include/hnnstereo/hnnstereo.h lib/cmake/hnnstereo/hnnstereoConfig.cmake
             lib/cmake/hnnstereo/hnnstereoConfigVersion.cmake lib/pkgconfig/hnnstereo.pc)
  if(NOT EXISTS ${prefix}/${file})
    message(FATAL_ERROR "the install lacks ${file}")
  endif()
endforeach()

set(launcher "")
if(LAUNCHER)
  set(launcher -DCMAKE_CXX_COMPILER_LAUNCHER=${LAUNCHER})
endif()
# A sanitizer build (HNNSTEREO_SANITIZE) installs instrumented static libraries: a program that
# links them needs the sanitizer's runtime too, as any user of such a build would.
set(sanitize_flags "")
if(SANITIZE)
  set(sanitize_flags "-DCMAKE_CXX_FLAGS=-fsanitize=${SANITIZE}"
                     "-DCMAKE_EXE_LINKER_FLAGS=-fsanitize=${SANITIZE}")
endif()
# Only the prefix: no path into the source or build tree reaches the example.
run(${CMAKE_COMMAND} -S ${SOURCE_DIR}/examples/cpp -B ${example_build} -G Ninja
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${prefix} ${launcher} ${sanitize_flags})
run(${CMAKE_COMMAND} --build ${example_build})
run(${example_build}/match_pair ${teddy}/im2.png ${teddy}/im6.png 64)
set(example_output "${run_output}")
string(REGEX MATCH "^([0-9]+) matches" _ "${example_output}")
set(example_count ${CMAKE_MATCH_1})

run(${CLI} match --left ${teddy}/im2.png --right ${teddy}/im6.png --rectified --max-disparity 64
    --out ${BUILD_DIR}/api-test/cli_matches.csv --quiet)
file(STRINGS ${BUILD_DIR}/api-test/cli_matches.csv rows)
list(LENGTH rows cli_rows)
math(EXPR cli_count "${cli_rows} - 1")
message(STATUS "example: ${example_output}")
math(EXPR install_s "${installed} - ${start}")
message(STATUS "install took ${install_s} s; example ${example_count} matches, CLI ${cli_count}")
if(NOT example_count STREQUAL cli_count)
  message(FATAL_ERROR "the example found ${example_count} matches, the CLI ${cli_count}")
endif()

# pkg-config sees the same package.
find_program(PKG_CONFIG pkg-config)
if(PKG_CONFIG)
  set(ENV{PKG_CONFIG_PATH} ${prefix}/lib/pkgconfig)
  run(${PKG_CONFIG} --libs --cflags hnnstereo)
  if(NOT run_output MATCHES "-lhnnstereo")
    message(FATAL_ERROR "pkg-config hnnstereo: ${run_output}")
  endif()
endif()

# The library is the matcher and the sensing, not the synthetic cell or the evaluation: neither
# their archives are installed nor their symbols linked into a program that uses the package.
foreach(library hnnstereo_synth hnnstereo_eval)
  if(EXISTS ${prefix}/lib/lib${library}.a)
    message(FATAL_ERROR "the install holds lib${library}.a")
  endif()
endforeach()
find_program(NM nm)
if(NM)
  run(${NM} -C ${example_build}/match_pair)
  foreach(symbol "vision::RenderScene" "vision::EvaluatePair" "vision::CompareWithTruth")
    string(FIND "${run_output}" "${symbol}" at)
    if(NOT at EQUAL -1)
      message(FATAL_ERROR "a program using the package links ${symbol}")
    endif()
  endforeach()
endif()
