# The live view's page at build time (serve/CMakeLists.txt runs this with cmake -P): installs the npm packages of
# package-lock.json with `npm ci` in WORK, then copies the ES modules the page imports into OUT/vendor (next to the
# page's own files), so that `twin serve` serves them itself: the browser fetches nothing from the network.
#   -DNPM=path -DSRC=serve/page -DWORK=build dir for node_modules -DOUT=build/serve/www -DSTAMP=file to touch
foreach(v NPM SRC WORK OUT STAMP)
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
file(TOUCH ${STAMP})
