# ctest's fuzz_build_configures_on_a_bootstrapped_machine: configures the fuzz
# build (clang, -DSKINTUNE_FUZZ=ON) in a fresh folder, as docs/INPUTS.md says
# to; fails with CMake's own message when a package is missing.
#   cmake -DSOURCE=... -DBINARY=... -DCLANG=... -DCLANGXX=... -P configure_fuzz_build.cmake
if(NOT CLANG OR NOT CLANGXX)
  message(FATAL_ERROR "clang not found: run scripts/bootstrap (it installs clang, libclang-rt-dev and libstb-dev)")
endif()
file(REMOVE_RECURSE ${BINARY})
execute_process(
  COMMAND ${CMAKE_COMMAND} -S ${SOURCE} -B ${BINARY} -DCMAKE_C_COMPILER=${CLANG} -DCMAKE_CXX_COMPILER=${CLANGXX}
          -DSKINTUNE_FUZZ=ON -DSKINTUNE_BUILD_BENCH=OFF -DCMAKE_BUILD_TYPE=RelWithDebInfo
  RESULT_VARIABLE result)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "the fuzz build does not configure on this machine (a package missing from scripts/bootstrap?)")
endif()
