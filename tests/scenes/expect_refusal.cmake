# Runs `incise check SCENE`; passes only when it exits non-zero and prints EXPECTED.
execute_process(COMMAND ${INCISE} check ${SCENE} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(code EQUAL 0)
  message(FATAL_ERROR "incise check accepted ${SCENE}:\n${out}${err}")
endif()
string(FIND "${out}${err}" "${EXPECTED}" at)
if(at EQUAL -1)
  message(FATAL_ERROR "expected '${EXPECTED}' in:\n${out}${err}")
endif()
