# Runs one consumer program and checks its output against skintune's reference.
#   cmake -DSKINTUNE=<installed skintune> -DMODEL=<gltf> -DTIME=<s> -DWORK=<dir>
#         -DPROGRAM=<consumer exe> -DKIND=runtime|embedded [-DDB=<db>] -P check.cmake
# runtime:  PROGRAM MODEL DB WORK/out.stv TIME WORK/cache (fresh cache: the second start must build nothing)
# embedded: `skintune skin --palette-out` writes the frame's palette; PROGRAM MODEL palette WORK/out.stv
# Then `skintune skin --check WORK/out.stv --variant <the variant the program printed>`.
foreach(required SKINTUNE MODEL TIME WORK PROGRAM KIND)
  if(NOT DEFINED ${required})
    message(FATAL_ERROR "check.cmake: -D${required}= is required")
  endif()
endforeach()
file(REMOVE_RECURSE "${WORK}")
file(MAKE_DIRECTORY "${WORK}")
set(frame skin --mesh "${MODEL}" --animation 0 --time "${TIME}")

if(KIND STREQUAL "runtime")
  execute_process(COMMAND "${PROGRAM}" "${MODEL}" "${DB}" "${WORK}/out.stv" "${TIME}" "${WORK}/cache"
    RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
else()
  execute_process(COMMAND "${SKINTUNE}" ${frame} --palette-out "${WORK}/palette.bin"
    RESULT_VARIABLE rc OUTPUT_QUIET ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "skintune skin --palette-out failed (${rc}): ${err}")
  endif()
  execute_process(COMMAND "${PROGRAM}" "${MODEL}" "${WORK}/palette.bin" "${WORK}/out.stv"
    RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
endif()
message("${out}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "${PROGRAM} failed (${rc}): ${err}")
endif()
if(NOT out MATCHES "variant: ([^\n]+)")
  message(FATAL_ERROR "${PROGRAM} did not say which variant it ran")
endif()
set(variant "${CMAKE_MATCH_1}")
execute_process(COMMAND "${SKINTUNE}" ${frame} --check "${WORK}/out.stv" --variant "${variant}"
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
message("${out}")
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "the output of ${PROGRAM} (${variant}) is not the reference's: ${err}")
endif()
