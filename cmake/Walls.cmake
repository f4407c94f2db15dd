# The walls between the libraries (docs/architecture.md), checked by the `walls` test:
#  - what each library's sources include (tests/walls/check_walls.cmake reads the tree), and
#  - what each library links, directly or through others (written here at configure time, after every target is
#    defined, to ${CMAKE_BINARY_DIR}/walls/links.txt, one line per library: "<library>: <everything it links>").
# The rules themselves are in tests/walls/check_walls.cmake.

# cw_link_closure(<target> <out-var>): every target and library <target> links, transitively.
function(cw_link_closure target out)
  set(seen "")
  set(todo ${target})
  while(todo)
    list(POP_FRONT todo t)
    # $<LINK_ONLY:x> and other generator expressions around a name: keep the name.
    string(REGEX REPLACE "^\\$<[A-Z_]+:(.*)>$" "\\1" t "${t}")
    if(t STREQUAL "" OR t IN_LIST seen)
      continue()
    endif()
    list(APPEND seen ${t})
    if(NOT TARGET ${t})
      continue()
    endif()
    get_target_property(aliased ${t} ALIASED_TARGET)
    if(aliased)
      list(APPEND todo ${aliased})
      continue()
    endif()
    get_target_property(type ${t} TYPE)
    set(props INTERFACE_LINK_LIBRARIES)
    if(NOT type STREQUAL "INTERFACE_LIBRARY")
      list(APPEND props LINK_LIBRARIES)
    endif()
    foreach(p ${props})
      get_target_property(libs ${t} ${p})
      if(libs)
        list(APPEND todo ${libs})
      endif()
    endforeach()
  endwhile()
  list(REMOVE_ITEM seen ${target})
  set(${out} "${seen}" PARENT_SCOPE)
endfunction()

# cw_write_link_closures(<targets...>): the closures of our libraries and test suites, for the walls test.
function(cw_write_link_closures)
  set(text "")
  foreach(t ${ARGN})
    if(TARGET ${t})
      cw_link_closure(${t} closure)
      string(APPEND text "${t}: ${closure}\n")
    endif()
  endforeach()
  file(WRITE ${CMAKE_BINARY_DIR}/walls/links.txt "${text}")
  # Whether the simulator was built (CW_SIM): the rules for the `twin` executable differ.
  if(CW_SIM)
    file(WRITE ${CMAKE_BINARY_DIR}/walls/links.txt.sim "ON\n")
  else()
    file(WRITE ${CMAKE_BINARY_DIR}/walls/links.txt.sim "\n")
  endif()
endfunction()
