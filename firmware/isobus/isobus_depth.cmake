# The sowing-depth controller as an ISOBUS implement (TC client, depth DDOP; issue 42), on the
# fertilizer's network and TC client (isobus.cmake). Included from firmware/CMakeLists.txt after
# isobus.cmake.
# the vector replay's loop is shared (replay_isobus.c); each program brings its controller
# (replay_ctl.h): the fertilizer's replay_fert.c, the depth's replay_depth.c
target_sources(replay_isobus PRIVATE ${ISOBUS_DIR}/replay_fert.c)
# the network, the TC client and the DDOP writers are the fertilizer build's files; the depth
# program links them without the fertilizer controller (iso_fert.c)
add_library(agrihil_isobus_depth STATIC ${ISOBUS_DIR}/iso_ddop.c ${ISOBUS_DIR}/iso_net.c
            ${ISOBUS_DIR}/iso_tc.c ${ISOBUS_DIR}/iso_depth.c)
target_include_directories(agrihil_isobus_depth PUBLIC ${ISOBUS_DIR})
target_link_libraries(agrihil_isobus_depth PUBLIC agrihil_adapters)
# the ISOBUS programs' loop (iso_app.c: app_run's contract, a whole CTS window per step), the
# fertilizer's program (isobus.cmake) and the depth's
add_library(agrihil_iso_app STATIC ${ISOBUS_DIR}/iso_app.c)
target_link_libraries(agrihil_iso_app PUBLIC agrihil_app)
target_link_libraries(agrihil-fertilizer-isobus-fw PRIVATE agrihil_iso_app)
add_executable(agrihil-sowing-depth-isobus-fw ${ISOBUS_DIR}/depth_isobus_main.c)
target_link_libraries(agrihil-sowing-depth-isobus-fw PRIVATE agrihil_isobus_depth agrihil_iso_app)
# the depth vectors' replay and the depth DDOP check (targets without BUILD_TESTING too: the
# pytest suite tests/firmware/test_isobus_depth_firmware.py builds and runs them)
add_executable(replay_isobus_depth ${ISOBUS_DIR}/replay_isobus.c ${ISOBUS_DIR}/replay_depth.c)
target_link_libraries(replay_isobus_depth PRIVATE agrihil_isobus_depth)
add_executable(test_iso_ddop_depth ${ISOBUS_DIR}/test_iso_ddop_depth.c)
target_link_libraries(test_iso_ddop_depth PRIVATE agrihil_isobus_depth)

if(BUILD_TESTING)
  # the depth vectors the Python build records (python -m reference_controllers.vectors.isobus_depth)
  file(GLOB ISOBUS_DEPTH_VECTORS ${ISOBUS_DIR}/data/depth-isobus-*.frames)
  add_test(NAME isobus_depth_vectors COMMAND replay_isobus_depth ${ISOBUS_DEPTH_VECTORS})
  add_test(NAME isobus_depth_ddop
           COMMAND test_iso_ddop_depth ${ISOBUS_DIR}/data/depth-ddop.txt)
  set(DEPTHFW $<TARGET_FILE:agrihil-sowing-depth-isobus-fw>)
  set(CLI ${CMAKE_CURRENT_SOURCE_DIR}/tests/expect_exit.sh)
  add_test(NAME isobus_depth_cli_params_accepted
           COMMAND sh ${CLI} 1 "127.0.0.1:9" ${DEPTHFW} --bus socketcand:127.0.0.1:9
                   --param kp0=3 --param address=130 --param identity_number=3394
                   --param default_depth_mm=35 --param min_depth_mm=20 --param max_depth_mm=50
                   --param latency_ms=800 --param fixed_depth_mm=40 --param actual=setpoint
                   --param fallback=hold)
  add_test(NAME isobus_depth_cli_bad_actual COMMAND sh ${CLI} 2 "actual must be sensed or setpoint"
           ${DEPTHFW} --bus socketcand:127.0.0.1:9 --param actual=guess)
  add_test(NAME isobus_depth_cli_bad_fallback COMMAND sh ${CLI} 2 "fallback must be default or hold"
           ${DEPTHFW} --bus socketcand:127.0.0.1:9 --param fallback=never)
  add_test(NAME isobus_depth_cli_bad_range
           COMMAND sh ${CLI} 2 "need 0 < min_depth_mm <= default_depth_mm <= max_depth_mm <= 100"
           ${DEPTHFW} --bus socketcand:127.0.0.1:9 --param default_depth_mm=70)
  add_test(NAME isobus_depth_cli_bad_fixed
           COMMAND sh ${CLI} 2 "fixed_depth_mm must be 0 or within the depth range"
           ${DEPTHFW} --bus socketcand:127.0.0.1:9 --param fixed_depth_mm=5)
  add_test(NAME isobus_depth_cli_unknown_param COMMAND sh ${CLI} 2 "unknown parameter 'width_m'"
           ${DEPTHFW} --bus socketcand:127.0.0.1:9 --param width_m=3)
endif()
