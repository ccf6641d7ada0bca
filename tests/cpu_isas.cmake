# SKINTUNE_CPU_ISAS (cpu_kernels/CMakeLists.txt) at configure time, on a throwaway build
# folder: an unknown instruction set is one error naming it, before anything is built;
# "native" picks one table and says which.
#   cmake -DSOURCE_DIR=... -DWORK_DIR=... -DGENERATOR=... -P cpu_isas.cmake
file(REMOVE_RECURSE ${WORK_DIR})
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/bad -G ${GENERATOR}
                        -DSKINTUNE_CPU_ISAS=avx2\;sse9
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0)
  message(FATAL_ERROR "SKINTUNE_CPU_ISAS=avx2;sse9 configured without an error")
endif()
if(NOT err MATCHES "SKINTUNE_CPU_ISAS: unknown instruction set 'sse9'")
  message(FATAL_ERROR "SKINTUNE_CPU_ISAS=avx2;sse9: the error does not name it:\n${err}")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/native -G ${GENERATOR}
                        -DSKINTUNE_CPU_ISAS=native
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "SKINTUNE_CPU_ISAS=native failed to configure:\n${err}")
endif()
if(NOT out MATCHES "SKINTUNE_CPU_ISAS=native: the (avx512|avx2|baseline) table only")
  message(FATAL_ERROR "SKINTUNE_CPU_ISAS=native did not say which table:\n${out}")
endif()
file(REMOVE_RECURSE ${WORK_DIR})
