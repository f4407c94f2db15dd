# The live view's page at build time (serve/CMakeLists.txt runs this with cmake -P): installs the npm packages of
# package-lock.json with `npm ci` in WORK, then copies the ES modules the page imports into OUT/vendor (next to the
# page's own files), so that `twin serve` serves them itself: the browser fetches nothing from the network.
# It also writes GEN, a C++ source holding the JSON schemas of the Foxglove messages the server's Foxglove channels
# carry (serve/foxglove_schemas.hpp), read from @foxglove/schemas with node.
#   -DNPM=path -DNODE=path -DSRC=serve/page -DWORK=build dir for node_modules -DOUT=build/serve/www -DGEN=.cpp
#   -DSTAMP=file to touch
foreach(v NPM NODE SRC WORK OUT GEN STAMP)
  if(NOT DEFINED ${v})
    message(FATAL_ERROR "bundle.cmake: -D${v}=... missing")
  endif()
endforeach()
file(MAKE_DIRECTORY ${WORK})
file(COPY ${SRC}/package.json ${SRC}/package-lock.json DESTINATION ${WORK})
# --prefer-offline: a machine that has fetched these versions once (npm's cache, ~/.npm) needs no network.
execute_process(COMMAND ${NPM} ci --no-audit --no-fund --ignore-scripts --prefer-offline
                WORKING_DIRECTORY ${WORK} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR
    "The live view's 3D page needs three.js and urdf-loader from the npm registry, and `npm ci` failed (exit ${rc}) "
    "in ${WORK}:\n${out}\n${err}\n"
    "What to do: give this machine access to https://registry.npmjs.org (or set npm_config_registry to a mirror), "
    "or fill npm's cache (~/.npm) from a machine that has it, then build again. serve/page/package-lock.json names "
    "the exact versions. The build stops here rather than serve a page without three.js.")
endif()
set(nm ${WORK}/node_modules)
set(files
  three/LICENSE
  three/build/three.module.js
  three/build/three.core.js
  three/examples/jsm/controls/OrbitControls.js
  three/examples/jsm/loaders/STLLoader.js
  three/examples/jsm/loaders/ColladaLoader.js
  three/examples/jsm/loaders/TGALoader.js
  three/examples/jsm/loaders/collada/ColladaParser.js
  three/examples/jsm/loaders/collada/ColladaComposer.js
  urdf-loader/package.json
  urdf-loader/src/URDFLoader.js
  urdf-loader/src/URDFClasses.js)
file(REMOVE_RECURSE ${OUT}/vendor)
foreach(f ${files})
  if(NOT EXISTS ${nm}/${f})
    message(FATAL_ERROR "The live view's 3D page: ${nm}/${f} is not there after `npm ci`: the package's layout "
                        "changed; update the list in serve/page/bundle.cmake to the version of package-lock.json")
  endif()
  get_filename_component(dir ${f} DIRECTORY)
  file(COPY ${nm}/${f} DESTINATION ${OUT}/vendor/${dir})
endforeach()

# The Foxglove schemas, as the package of package-lock.json has them (one JSON text each).
set(schemas SceneUpdate)
set(cases "")
foreach(name ${schemas})
  execute_process(COMMAND ${NODE} -e
                  "process.stdout.write(JSON.stringify(require('@foxglove/schemas/jsonschema')['${name}']))"
                  WORKING_DIRECTORY ${WORK} RESULT_VARIABLE rc OUTPUT_VARIABLE schema ERROR_VARIABLE err)
  if(NOT rc EQUAL 0 OR NOT schema MATCHES "^{")
    message(FATAL_ERROR "The Foxglove schema ${name} could not be read from @foxglove/schemas in ${WORK} (exit ${rc}):"
                        "\n${err}\nupdate serve/page/bundle.cmake to the version of package-lock.json")
  endif()
  string(APPEND cases "  if (name == \"foxglove.${name}\") return R\"cwschema(${schema})cwschema\";\n")
endforeach()
file(WRITE ${GEN}.new
  "// Written by serve/page/bundle.cmake from @foxglove/schemas (serve/page/package-lock.json's version).\n"
  "#include \"cellwright/serve/foxglove_schemas.hpp\"\n\n"
  "namespace cellwright::serve {\n\n"
  "std::string_view foxglove_schema(std::string_view name) {\n${cases}  return {};\n}\n\n"
  "}  // namespace cellwright::serve\n")
file(COPY_FILE ${GEN}.new ${GEN} ONLY_IF_DIFFERENT)
file(REMOVE ${GEN}.new)
file(TOUCH ${STAMP})
