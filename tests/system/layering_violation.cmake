# ctest LayeringCatchesAnUpwardInclude: scripts/check_layers.py on a copy of include/ and src/ in which one core file
# includes a stream header must fail and name that file and include.
#   cmake -DPYTHON=... -DSOURCE_DIR=... -DWORK_DIR=... -P layering_violation.cmake
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
foreach(folder include src apps python examples bench tests fuzz)
  if(EXISTS ${SOURCE_DIR}/${folder})
    file(COPY ${SOURCE_DIR}/${folder} DESTINATION ${WORK_DIR})
  endif()
endforeach()
set(planted ${WORK_DIR}/src/core/units.cpp)
file(READ ${planted} text)
file(WRITE ${planted} "#include \"feedid/stream/scan.hpp\"\n${text}")
execute_process(COMMAND ${PYTHON} ${SOURCE_DIR}/scripts/check_layers.py ${WORK_DIR}
                RESULT_VARIABLE result OUTPUT_VARIABLE output ERROR_VARIABLE errors)
if(result EQUAL 0)
  message(FATAL_ERROR "check_layers.py passed a tree in which core includes stream:\n${output}")
endif()
if(NOT output MATCHES "src/core/units.cpp:1: core includes feedid/stream/scan.hpp, a higher area \\(stream\\)")
  message(FATAL_ERROR "check_layers.py failed without naming the planted include:\n${output}${errors}")
endif()
message(STATUS "check_layers.py caught the planted include: ${output}")
