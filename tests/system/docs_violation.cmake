# ctest DocsCatchesABrokenLink: scripts/check_docs.py on a copy of the tree with a link to a missing file, a link to a
# missing heading and a pointer to a note outside the repository planted must fail and name each of them.
#   cmake -DPYTHON=... -DSOURCE_DIR=... -DWORK_DIR=... -P docs_violation.cmake
file(REMOVE_RECURSE ${WORK_DIR})
file(MAKE_DIRECTORY ${WORK_DIR})
foreach(entry README.md CHANGELOG.md docs include src apps python examples bench tests fuzz scripts)
  if(EXISTS ${SOURCE_DIR}/${entry})
    file(COPY ${SOURCE_DIR}/${entry} DESTINATION ${WORK_DIR})
  endif()
endforeach()
execute_process(COMMAND ${PYTHON} ${SOURCE_DIR}/scripts/check_docs.py ${WORK_DIR}
                RESULT_VARIABLE result OUTPUT_VARIABLE output ERROR_VARIABLE errors)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "check_docs.py fails on the unchanged copy, so the planted problems would prove nothing:\n"
                      "${output}${errors}")
endif()
file(APPEND ${WORK_DIR}/docs/architecture.md "\nSee [the missing guide](missing-guide.md).\n")
file(APPEND ${WORK_DIR}/README.md "\n[A step identify does not have](docs/identify.md#step-7)\n")
set(note METHOD)  # spelled in pieces, so that this file points nowhere itself
file(READ ${WORK_DIR}/src/core/units.cpp text)
file(WRITE ${WORK_DIR}/src/core/units.cpp "// as ${note}.md says\n${text}")
execute_process(COMMAND ${PYTHON} ${SOURCE_DIR}/scripts/check_docs.py ${WORK_DIR}
                RESULT_VARIABLE result OUTPUT_VARIABLE output ERROR_VARIABLE errors)
if(result EQUAL 0)
  message(FATAL_ERROR "check_docs.py passed a tree with a broken link planted:\n${output}")
endif()
foreach(expected "docs/architecture.md:[0-9]+: the link missing-guide.md names no file"
                 "README.md:[0-9]+: the link docs/identify.md#step-7: identify.md has no heading #step-7"
                 "src/core/units.cpp:1: points to a note outside the repository")
  if(NOT output MATCHES "${expected}")
    message(FATAL_ERROR "check_docs.py failed without naming '${expected}':\n${output}${errors}")
  endif()
endforeach()
message(STATUS "check_docs.py caught the planted problems:\n${output}")
