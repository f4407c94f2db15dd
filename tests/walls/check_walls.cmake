# The walls test (docs/architecture.md, "Walls"): fails, naming each offence, when a library includes a header or
# links a package it must not.
#   cmake -DSOURCE_DIR=<repo> -DLINKS=<build>/walls/links.txt -P tests/walls/check_walls.cmake
# The rules:
#   controller (task, petri, runtime)  no MuJoCo, OpenGL/OSMesa, OpenCV; nothing of twin or vision
#   models                             no MuJoCo, OpenGL/OSMesa, OpenCV; nothing of twin, vision, drivers, runtime
#   drivers                            no MuJoCo, OpenGL/OSMesa, OpenCV; nothing of twin, vision, runtime
#   common                             nothing of ours but common; no MuJoCo, OpenGL/OSMesa, OpenCV
#   vision (twin/vision)               OpenCV yes; no MuJoCo, OpenGL/OSMesa; nothing of twin
#   emulate (twin/emulate)             no MuJoCo, OpenGL/OSMesa, OpenCV; nothing of twin, vision, runtime; none of the
#                                      drivers' protocol code (drivers/serial, movemaster, val2): each checks the other
#   twin                               OpenCV only in rendering and reports (render, video, scenario/gantt, scenario/run,
#                                      scenario/campaign: its chart)
#   every library                      nothing of tools/
# Each suite of tests links what its library may link (plus GoogleTest).
cmake_minimum_required(VERSION 3.25)

if(NOT SOURCE_DIR OR NOT LINKS)
  message(FATAL_ERROR "usage: cmake -DSOURCE_DIR=<repo> -DLINKS=<links.txt> -P check_walls.cmake")
endif()

set(heavy "mujoco/|opencv2/|GL/|osmesa")
set(offences "")

# check_includes(<name> <forbidden regex> <globs...> [EXCEPT <regex of files allowed>])
function(check_includes name forbidden)
  cmake_parse_arguments(ARG "" "EXCEPT" "" ${ARGN})
  set(files "")
  foreach(g ${ARG_UNPARSED_ARGUMENTS})
    file(GLOB_RECURSE found ${SOURCE_DIR}/${g})
    list(APPEND files ${found})
  endforeach()
  list(FILTER files INCLUDE REGEX "\\.(cpp|hpp|h)$")
  if(NOT files)
    set(offences "${offences}  ${name}: no source files found under ${ARG_UNPARSED_ARGUMENTS} (is the layout as the rules say?)\n"
        PARENT_SCOPE)
    return()
  endif()
  set(out "${offences}")
  foreach(f ${files})
    file(RELATIVE_PATH rel ${SOURCE_DIR} ${f})
    if(ARG_EXCEPT AND rel MATCHES "${ARG_EXCEPT}")
      continue()
    endif()
    file(STRINGS ${f} lines REGEX "^[ \t]*#[ \t]*include")
    foreach(line ${lines})
      if(line MATCHES "[<\"](${forbidden})")
        string(STRIP "${line}" line)
        string(APPEND out "  ${name}: ${rel} has ${line}\n")
      endif()
    endforeach()
  endforeach()
  set(offences "${out}" PARENT_SCOPE)
endfunction()

set(tools_reach "tools/|commands\\.hpp")
check_includes(controller "${heavy}|cellwright/(twin|vision)/|${tools_reach}"
               "controller/include/*" "controller/src/*" "controller/runtime/*")
check_includes(models "${heavy}|cellwright/(twin|vision|drivers|runtime)/|${tools_reach}" "models/*")
check_includes(drivers "${heavy}|cellwright/(twin|vision|runtime)/|${tools_reach}" "drivers/*")
check_includes(common "${heavy}|cellwright/(twin|vision|drivers|runtime|models|petri|task)/|${tools_reach}"
               "common/*")
check_includes(vision "mujoco/|GL/|osmesa|cellwright/twin/|${tools_reach}" "twin/vision/*")
check_includes(emulate "${heavy}|cellwright/(twin|vision|runtime)/|cellwright/drivers/(serial|movemaster|val2)/|${tools_reach}"
               "twin/emulate/*")
check_includes(twin "opencv2/" "twin/include/*" "twin/src/*"
               EXCEPT "^twin/(include/cellwright/twin|src)/(render\\.|video\\.|scenario/gantt\\.|scenario/run\\.|scenario/campaign\\.)")
check_includes(twin "${tools_reach}" "twin/include/*" "twin/src/*")

# Links, from the closures the configure step wrote.
set(mujoco_ocv_gl "mujoco|opencv_|OSMESA|osmesa")
set(link_rules
    "cellwright_controller|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime|drivers|models)"
    "cellwright_runtime|${mujoco_ocv_gl}|cellwright_(twin|vision)"
    "runtime_tests|${mujoco_ocv_gl}|cellwright_(twin|vision)"
    "controller_tests|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime)"
    "cellwright_models|${mujoco_ocv_gl}|cellwright_(twin|vision|drivers|runtime)"
    "models_tests|${mujoco_ocv_gl}|cellwright_(twin|vision|drivers|runtime)"
    "cellwright_drivers|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime)"
    "drivers_tests|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime)"
    "cellwright_common|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime|drivers|models|controller)"
    "cellwright_vision|mujoco|OSMESA|osmesa|cellwright_twin"
    "cellwright_emulate|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime)"
    "emulate_tests|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime)")
file(STRINGS ${LINKS} closures)
foreach(rule ${link_rules})
  string(REPLACE "|" ";" parts "${rule}")
  list(POP_FRONT parts lib)
  list(JOIN parts "|" forbidden)
  set(found FALSE)
  foreach(line ${closures})
    if(line MATCHES "^${lib}: (.*)$")
      set(found TRUE)
      string(REPLACE ";" " " linked "${CMAKE_MATCH_1}")
      separate_arguments(items UNIX_COMMAND "${linked}")
      foreach(item ${items})
        if(item MATCHES "(${forbidden})")
          string(APPEND offences "  ${lib}: links ${item}\n")
        endif()
      endforeach()
    endif()
  endforeach()
  if(NOT found)
    string(APPEND offences "  ${lib}: not in ${LINKS} (is the target still defined?)\n")
  endif()
endforeach()

if(offences)
  message(FATAL_ERROR "walls: a library reaches what it must not (docs/architecture.md):\n${offences}")
endif()
message(STATUS "walls: every library keeps to its side")
