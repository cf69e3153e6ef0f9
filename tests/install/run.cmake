# ctest install_consumer: `cmake --install` into a fresh prefix, then everything a user of the
# installed files does: the command (bundled robots found from bin/accura, not from the source
# tree), a host project with find_package(accura) built and run, the Python example with the
# installed wrapper and library. The prefix and the consumer's build are removed at the end.
# Arguments: -DBUILD_DIR= -DSOURCE_DIR= -DWORK_DIR= -DCXX= [-DPYTHON=]
cmake_minimum_required(VERSION 3.16)
set(prefix ${WORK_DIR}/prefix)
file(REMOVE_RECURSE ${WORK_DIR})

function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err WORKING_DIRECTORY ${WORK_DIR})
  if(NOT rc EQUAL 0)
    file(REMOVE_RECURSE ${WORK_DIR})
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  set(out "${out}" PARENT_SCOPE)
endfunction()

file(MAKE_DIRECTORY ${WORK_DIR})
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(f bin/accura lib/libaccura_plugin.so lib/libaccura_calib.a lib/libaccura_postproc.a
          include/accura_plugin.h include/accura/calib/robot.h include/accura/postproc/job.h
          share/accura/robots/kuka_kr16.xml share/accura/schema/accura-program.xsd
          share/accura/mappings/ipa_robot_accuracy.map share/accura/python/accura_plugin.py
          share/accura/freecad/accura_freecad.py share/accura/freecad/AccuraCompensate.FCMacro
          share/accura/README.md lib/cmake/accura/accuraConfig.cmake)
  if(NOT EXISTS ${prefix}/${f})
    file(REMOVE_RECURSE ${WORK_DIR})
    message(FATAL_ERROR "not installed: ${prefix}/${f}")
  endif()
endforeach()

# the installed command finds its robots under the prefix (the source tree's robots/ is hidden
# by an environment without ACCURA_ROBOTS_DIR: a robot name resolved there would differ)
set(ENV{ACCURA_ROBOTS_DIR} "")
unset(ENV{ACCURA_ROBOTS_DIR})
run(${prefix}/bin/accura fk --robot kuka_kr16 --q 10,-80,70,20,30,40)
set(installed_fk "${out}")
run(${BUILD_DIR}/cli/accura fk --robot ${SOURCE_DIR}/robots/kuka_kr16.xml --q 10,-80,70,20,30,40)
if(NOT installed_fk STREQUAL out)
  file(REMOVE_RECURSE ${WORK_DIR})
  message(FATAL_ERROR "installed accura fk: '${installed_fk}', the build's: '${out}'")
endif()
# a robot that only the prefix has: found by name, so the prefix's robots directory is the one used
file(COPY_FILE ${prefix}/share/accura/robots/kuka_kr16.xml ${prefix}/share/accura/robots/installed_only.xml)
run(${prefix}/bin/accura fk --robot installed_only --q 10,-80,70,20,30,40)
if(NOT out STREQUAL installed_fk)
  file(REMOVE_RECURSE ${WORK_DIR})
  message(FATAL_ERROR "installed accura did not read its robots from ${prefix}/share/accura/robots: '${out}'")
endif()

# a host project: find_package(accura), the three targets, its output equal to the command's
run(${CMAKE_COMMAND} -S ${SOURCE_DIR}/tests/install/consumer -B ${WORK_DIR}/consumer -DCMAKE_PREFIX_PATH=${prefix}
    -DCMAKE_CXX_COMPILER=${CXX} -DCMAKE_BUILD_TYPE=Release)
run(${CMAKE_COMMAND} --build ${WORK_DIR}/consumer)
run(${WORK_DIR}/consumer/consumer)
if(NOT out STREQUAL installed_fk)
  file(REMOVE_RECURSE ${WORK_DIR})
  message(FATAL_ERROR "consumer printed '${out}', accura fk '${installed_fk}'")
endif()

# the Python example, run from the installed files only (it finds its module next to itself, and
# the wrapper finds the installed library without --lib or ACCURA_PLUGIN_LIB)
if(PYTHON)
  run(${CMAKE_COMMAND} -E env --unset=ACCURA_PLUGIN_LIB PYTHONDONTWRITEBYTECODE=1 ${PYTHON} ${prefix}/share/accura/python/example.py
      --model ${SOURCE_DIR}/tests/data/plugin/kr16_calibrated.xml)
endif()
file(REMOVE_RECURSE ${WORK_DIR})
message(STATUS "install, find_package(accura), installed command and Python example: passed")
