# The walls test (docs/architecture.md, "Walls"): fails, naming each offence, when a library includes a header or
# links a package it must not.
#   cmake -DSOURCE_DIR=<repo> -DLINKS=<build>/walls/links.txt -P tests/walls/check_walls.cmake
# The rules:
#   controller (task, petri, runtime)  no MuJoCo, OpenGL/OSMesa, OpenCV; nothing of twin, vision, emulate or cell
#   models                             no MuJoCo, OpenGL/OSMesa, OpenCV; nothing of twin, vision, drivers, runtime, cell
#   drivers                            no MuJoCo, OpenGL/OSMesa, OpenCV; nothing of twin, vision, runtime, cell
#   common                             nothing of ours but common; no MuJoCo, OpenGL/OSMesa, OpenCV
#   vision                             OpenCV yes; no MuJoCo, OpenGL/OSMesa; nothing of twin or cell
#   emulate                            no MuJoCo, OpenGL/OSMesa, OpenCV; nothing of twin, vision, runtime, cell; none of
#                                      the drivers' protocol code (drivers/serial, movemaster, val2, modbus): each checks
#                                      the other
#   twin/model (the twin's facts)      no MuJoCo, OpenGL/OSMesa, OpenCV; nothing of cell
#   twin (the simulator)               nothing of cell (the application); OpenCV only in rendering and the video
#   cell (the application layer)       no MuJoCo, OpenGL/OSMesa; of the twin only its MuJoCo-free facts (twin/model);
#                                      nothing of cell/sim (the simulated rig); OpenCV only in the reports (cell/report,
#                                      and the campaign's chart); campaigns and suites never build a run (cell/sim/run)
#   distributed (DDS transport)        no MuJoCo, OpenGL/OSMesa, OpenCV; nothing of twin, vision, emulate or cell
#   serve (the live view's server)     no MuJoCo, OpenGL/OSMesa, OpenCV, DDS; nothing of ours but common
#   cell/sim (the simulated rig), twin nothing of the live view: no serve, no cell/live, no websocketpp or asio (the
#                                      live view is an application above the simulator, never inside it); the cell's
#                                      stages neither
#   cell/live (`twin serve`'s loop)    anything below it, nothing of the tools
#   controller, models, drivers, common  no DDS (Fast DDS, Fast CDR) and nothing of distributed: the runtime does not
#                                      know whether a robot is remote
#   every library                      nothing of tools/
#   controller/runtime                 no injected-fault concepts: no line names InjectedFault, new_faults or
#                                      lost_signal (the rig injects faults and logs them)
# The `twin` executable built with CW_SIM=OFF links no MuJoCo, OSMesa or Assimp (checked when the closures file says
# it was built so).
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
set(dds "fastdds/|fastrtps/|fastcdr/|cellwright/distributed/")
set(cell_libs "cellwright/(cell|emulate)/")
check_includes(controller "${heavy}|${dds}|cellwright/(twin|vision)/|${cell_libs}|${tools_reach}"
               "controller/include/*" "controller/src/*" "controller/runtime/*")
check_includes(models "${heavy}|${dds}|cellwright/(twin|vision|drivers|runtime)/|${cell_libs}|${tools_reach}" "models/*")
check_includes(drivers "${heavy}|${dds}|cellwright/(twin|vision|runtime)/|${cell_libs}|${tools_reach}" "drivers/*")
check_includes(common "${heavy}|${dds}|cellwright/(twin|vision|drivers|runtime|models|petri|task|cell|emulate)/|${tools_reach}"
               "common/*")
check_includes(vision "mujoco/|GL/|osmesa|cellwright/(twin|cell)/|${tools_reach}" "vision/*")
check_includes(emulate "${heavy}|cellwright/(twin|vision|runtime|cell)/|cellwright/drivers/(serial|movemaster|val2|modbus)/|${tools_reach}"
               "emulate/*")
# The DDS transport carries the runtime's queues; it knows no simulator, vision or application.
check_includes(distributed "${heavy}|cellwright/(twin|vision|cell|emulate)/|${tools_reach}" "distributed/*")
# The live view's server carries JSON texts and commands; it knows no simulator, runtime, robot or application.
check_includes(serve "${heavy}|${dds}|cellwright/(twin|vision|cell|emulate|runtime|petri|task|drivers|models)/|${tools_reach}"
               "serve/*")
# The twin's MuJoCo-free facts.
check_includes(twin_model "${heavy}|cellwright/(cell|vision|emulate)/|${tools_reach}" "twin/model/*")
# The simulator knows nothing of scenarios, plans, rigs or reports.
check_includes(twin "cellwright/cell/|${tools_reach}" "twin/include/*" "twin/src/*")
check_includes(twin "opencv2/" "twin/include/*" "twin/src/*"
               EXCEPT "^twin/(include/cellwright/twin|src)/(render|video)\\.")
# The application layer: no simulator but its facts, no simulated rig.
set(simulator "cellwright/twin/(scene|render|video|mesh_import|sim/(world|sim_driver|world_plant|fault_injector|mirrored_driver|signals))")
set(cell_stages "cell/scenario/*" "cell/plan/*" "cell/rig/*" "cell/agent/*" "cell/report/*" "cell/campaign/*")
check_includes(cell "mujoco/|GL/|osmesa|${simulator}|cellwright/cell/sim/|${tools_reach}" ${cell_stages})
check_includes(cell "opencv2/" ${cell_stages} EXCEPT "^cell/(report/|campaign/(src|include/cellwright/cell)/campaign\\.)")
# Campaigns and suites read reports; they never build a run.
check_includes(campaign "cellwright/cell/sim/|cellwright/runtime/runtime\\.hpp" "cell/campaign/*")
# The simulated rig may reach everything but the tools and the live view above it.
set(live_view "cellwright/serve/|cellwright/cell/live/|websocketpp/|asio")
check_includes(cell_sim "${tools_reach}|${live_view}" "cell/sim/*")
check_includes(twin "${live_view}" "twin/*")
check_includes(cell "${live_view}" ${cell_stages})
# The live view's loop: above the simulated rig and the server, below the tools.
check_includes(cell_live "${tools_reach}" "cell/live/*")

# check_words(<name> <forbidden regex> <globs...>): no line of the files (code or comment) matches.
function(check_words name forbidden)
  set(files "")
  foreach(g ${ARGN})
    file(GLOB_RECURSE found ${SOURCE_DIR}/${g})
    list(APPEND files ${found})
  endforeach()
  list(FILTER files INCLUDE REGEX "\\.(cpp|hpp|h)$")
  if(NOT files)
    set(offences "${offences}  ${name}: no source files found under ${ARGN}\n" PARENT_SCOPE)
    return()
  endif()
  set(out "${offences}")
  foreach(f ${files})
    file(RELATIVE_PATH rel ${SOURCE_DIR} ${f})
    file(STRINGS ${f} lines REGEX "${forbidden}")
    foreach(line ${lines})
      string(STRIP "${line}" line)
      string(APPEND out "  ${name}: ${rel} has '${line}'\n")
    endforeach()
  endforeach()
  set(offences "${out}" PARENT_SCOPE)
endfunction()
# The runtime carries no injected-fault concepts: the rig injects faults and logs its injections itself.
check_words(runtime_faults "InjectedFault|new_faults|lost_signal" "controller/runtime/*")

# Links, from the closures the configure step wrote.
set(mujoco_ocv_gl "mujoco|opencv_|OSMESA|osmesa")
set(link_rules
    "cellwright_controller|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime|drivers|models|scenario|plan|rig|report|campaign|cell_sim)"
    "cellwright_runtime|${mujoco_ocv_gl}|fastrtps|fastcdr|cellwright_(twin|vision|distributed|scenario|plan|rig|report|campaign|cell_sim)"
    "cellwright_distributed|${mujoco_ocv_gl}|cellwright_(twin|vision|emulate|scenario|plan|rig|report|campaign|cell_sim)"
    "distributed_tests|${mujoco_ocv_gl}|cellwright_(twin|vision|emulate|scenario|plan|rig|report|campaign|cell_sim)"
    "runtime_tests|${mujoco_ocv_gl}|cellwright_(twin|vision)"
    "cellwright_serve|${mujoco_ocv_gl}|fastrtps|fastcdr|cellwright_(twin|vision|runtime|controller|drivers|models|emulate|distributed|scenario|plan|rig|report|campaign|cell_sim|cell_live)"
    "serve_tests|${mujoco_ocv_gl}|fastrtps|fastcdr|cellwright_(twin|vision|runtime|controller|drivers|models|emulate|distributed|scenario|plan|rig|report|campaign|cell_sim|cell_live)"
    "controller_tests|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime)"
    "cellwright_models|${mujoco_ocv_gl}|cellwright_(twin|vision|drivers|runtime)"
    "models_tests|${mujoco_ocv_gl}|cellwright_(twin|vision|drivers|runtime)"
    "cellwright_drivers|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime)"
    "drivers_tests|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime)"
    "cellwright_common|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime|drivers|models|controller)"
    "cellwright_vision|mujoco|OSMESA|osmesa|cellwright_twin|cellwright_(scenario|plan|rig|report|campaign|cell_sim)"
    "cellwright_emulate|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime)"
    "emulate_tests|${mujoco_ocv_gl}|cellwright_(twin|vision|runtime)"
    "cellwright_twin_model|${mujoco_ocv_gl}|cellwright_(twin$|vision|scenario|plan|rig|report|campaign|cell_sim)"
    "cellwright_scenario|mujoco|OSMESA|osmesa|assimp|cellwright_twin$|cellwright_(plan|rig|report|campaign|cell_sim)"
    "cellwright_plan|mujoco|OSMESA|osmesa|assimp|cellwright_twin$|cellwright_(rig|report|campaign|cell_sim)"
    "cellwright_rig|mujoco|OSMESA|osmesa|assimp|cellwright_twin$|cellwright_(report|campaign|cell_sim)"
    "cellwright_agent|mujoco|OSMESA|osmesa|assimp|opencv_|cellwright_twin$|cellwright_(report|campaign|cell_sim)"
    "cellwright_report|mujoco|OSMESA|osmesa|assimp|cellwright_twin$|cellwright_(plan|rig|campaign|cell_sim)"
    "cellwright_campaign|mujoco|OSMESA|osmesa|assimp|cellwright_twin$|cellwright_(rig|cell_sim)")
if(EXISTS ${LINKS}.sim)
  file(READ ${LINKS}.sim with_sim)
  string(STRIP "${with_sim}" with_sim)
else()
  set(with_sim "ON")
endif()
if(with_sim)
  # The simulator knows no application.
  list(APPEND link_rules "cellwright_twin|cellwright_(scenario|plan|rig|report|campaign|cell_sim|cell_live|serve)")
  # The simulated rig does not link the live view's server: the live view sits above the simulator (cell/live).
  list(APPEND link_rules "cellwright_cell_sim|cellwright_(serve|cell_live)")
else()
  # A twin for real robots only: no simulator in the executable.
  list(APPEND link_rules "twin|mujoco|OSMESA|osmesa|assimp|cellwright_twin$|cellwright_cell_sim|cellwright_cell_live")
endif()
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
