# The fertilizer controller as an ISOBUS implement (issue 27): address claim, TP, a Task
# Controller client, the DDOP, on the firmware's fertilizer adapter. Included from
# firmware/CMakeLists.txt after include(CTest).
set(ISOBUS_DIR ${CMAKE_CURRENT_SOURCE_DIR}/isobus)

# pure logic: frames in + step count -> frames out (no I/O, no clock, no allocation)
add_library(agrihil_isobus STATIC ${ISOBUS_DIR}/iso_ddop.c ${ISOBUS_DIR}/iso_net.c
            ${ISOBUS_DIR}/iso_tc.c ${ISOBUS_DIR}/iso_fert.c
            ${ISOBUS_DIR}/iso_pool.c ${ISOBUS_DIR}/iso_vt.c)
target_include_directories(agrihil_isobus PUBLIC ${ISOBUS_DIR})
target_link_libraries(agrihil_isobus PUBLIC agrihil_adapters)

add_executable(agrihil-fertilizer-isobus-fw ${ISOBUS_DIR}/isobus_main.c)
target_link_libraries(agrihil-fertilizer-isobus-fw PRIVATE agrihil_isobus agrihil_app)

# the vector replay and the DDOP check are targets even without BUILD_TESTING: the pytest
# suite (tests/firmware/test_isobus_firmware.py) builds and runs them too, as CI runs pytest
add_executable(replay_isobus ${ISOBUS_DIR}/replay_isobus.c)
target_link_libraries(replay_isobus PRIVATE agrihil_isobus)
add_executable(test_iso_ddop ${ISOBUS_DIR}/test_iso_ddop.c)
target_link_libraries(test_iso_ddop PRIVATE agrihil_isobus)
add_executable(test_iso_pool ${ISOBUS_DIR}/test_iso_pool.c)
target_link_libraries(test_iso_pool PRIVATE agrihil_isobus)
# the network layer alone sending the VT pool of 16 rows by ETP (replay_isobus.c's loop)
add_executable(replay_isobus_net ${ISOBUS_DIR}/replay_isobus.c ${ISOBUS_DIR}/replay_net.c)
target_link_libraries(replay_isobus_net PRIVATE agrihil_isobus)

if(BUILD_TESTING)
  # the shared vectors of the Python build: every frame the C controller sends must be the
  # Python controller's, byte for byte, in order
  set(ISOBUS_VECTORS isobus-drive.frames isobus-refused.frames isobus-contention.frames
      isobus-scripted-tc.frames isobus-scripted-tp.frames isobus-scripted-claims.frames
      isobus-scripted-transfers.frames isobus-scripted-eoma.frames isobus-tc-no-memory.frames)
  set(ISOBUS_VECTOR_PATHS)
  foreach(v ${ISOBUS_VECTORS})
    list(APPEND ISOBUS_VECTOR_PATHS ${AGRIHIL_VECTORS_DIR}/${v})
  endforeach()
  add_test(NAME isobus_vectors COMMAND replay_isobus ${ISOBUS_VECTOR_PATHS})
  # the replay fails on a vector with one byte changed, on one that lacks a frame the
  # controller sends, and on a missing file, and says where
  set(CLI ${CMAKE_CURRENT_SOURCE_DIR}/tests/expect_exit.sh)
  add_test(NAME isobus_vectors_detect_changed_byte
           COMMAND sh ${CLI} 1 "vector 14CBF781#1004FF1100010500, C controller 14CBF781#1004FF1100010400"
                   $<TARGET_FILE:replay_isobus> ${ISOBUS_DIR}/data/wrong-version.frames)
  add_test(NAME isobus_vectors_detect_missing_frame
           COMMAND sh ${CLI} 1 "vector 14CBF781#1004FF1100010400, C controller 18EAFF81#0FFE00"
                   $<TARGET_FILE:replay_isobus> ${ISOBUS_DIR}/data/missing-frame.frames)
  add_test(NAME isobus_vectors_detect_missing_file
           COMMAND sh ${CLI} 2 "no-such.frames: missing"
                   $<TARGET_FILE:replay_isobus> ${ISOBUS_DIR}/data/no-such.frames)

  # command line: agrihil-fertilizer-fw's contract, with the ISOBUS parameters by the Python's
  # names (exit 2 naming a bad argument, 1 naming the bus that failed)
  set(ISOFW $<TARGET_FILE:agrihil-fertilizer-isobus-fw>)
  add_test(NAME isobus_cli_params_accepted
           COMMAND sh ${CLI} 1 "127.0.0.1:9" ${ISOFW} --bus socketcand:127.0.0.1:9
                   --param mode=physical --param ff_coeff=4.39 --param address=129
                   --param identity_number=3879 --param width_m=3.0 --param speed=wheel
                   --param ddop=broken)
  add_test(NAME isobus_cli_bad_speed COMMAND sh ${CLI} 2 "parameter 'speed' must be ground or wheel"
           ${ISOFW} --bus socketcand:127.0.0.1:9 --param speed=radar)
  add_test(NAME isobus_cli_bad_ddop COMMAND sh ${CLI} 2 "parameter 'ddop' must be valid or broken"
           ${ISOFW} --bus socketcand:127.0.0.1:9 --param ddop=odd)
  add_test(NAME isobus_cli_bad_address COMMAND sh ${CLI} 2 "address must be an integer 0 .. 253"
           ${ISOFW} --bus socketcand:127.0.0.1:9 --param address=254)
  add_test(NAME isobus_cli_bad_width COMMAND sh ${CLI} 2 "width_m must be within (0, 30] m"
           ${ISOFW} --bus socketcand:127.0.0.1:9 --param width_m=0)
  add_test(NAME isobus_cli_bad_identity COMMAND sh ${CLI} 2 "identity_number must be an integer below 2^21"
           ${ISOFW} --bus socketcand:127.0.0.1:9 --param identity_number=2097152)
  add_test(NAME isobus_cli_unknown_param COMMAND sh ${CLI} 2 "unknown parameter 'gain'"
           ${ISOFW} --bus socketcand:127.0.0.1:9 --param gain=1)
  add_test(NAME isobus_cli_no_open_loop COMMAND sh ${CLI} 2 "unknown law 'open-loop'"
           ${ISOFW} --bus socketcand:127.0.0.1:9 --law open-loop)
  add_test(NAME isobus_cli_help COMMAND sh ${CLI} 0 "--param KEY=VALUE" ${ISOFW} --help)

  # the DDOP bytes: the C writer against the Python's meter_pool(), versions 4 and 3
  add_test(NAME isobus_ddop COMMAND test_iso_ddop ${AGRIHIL_VECTORS_DIR}/isobus-ddop.txt)

  # the operator interface on a VT (issue 39): the VT vectors the Python implement records
  # (python tests/firmware/isobus_vt_vectors.py) and its pool's bytes
  set(ISOBUS_VT_VECTORS)
  foreach(v operator defect-ignores-master defect-no-alarm defect-bad-pool defect-no-reconnect
          defect-meters-without-vt defect-no-store defect-slow-maintenance
          defect-ignores-calibration cross-row odd concurrent no-memory)
    list(APPEND ISOBUS_VT_VECTORS ${ISOBUS_DIR}/data/vt-${v}.frames)
  endforeach()
  add_test(NAME isobus_vt_vectors COMMAND replay_isobus ${ISOBUS_VT_VECTORS})
  add_test(NAME isobus_vt_pool COMMAND test_iso_pool ${ISOBUS_DIR}/data/vt-pool.txt)
  add_test(NAME isobus_vt_net_etp COMMAND replay_isobus_net ${ISOBUS_DIR}/data/vt-net-etp.frames)
  add_test(NAME isobus_vt_vectors_detect_changed_byte
           COMMAND sh ${CLI} 1 "vt-detect-changed-byte.frames:43 (step 4): vector 14E72681#C0FF18040000FFFF, C controller 14E72681#C0FF17040000FFFF"
                   $<TARGET_FILE:replay_isobus> ${ISOBUS_DIR}/data/vt-detect-changed-byte.frames)
  add_test(NAME isobus_vt_cli_bad_vt COMMAND sh ${CLI} 2 "parameter 'vt' must be yes or no"
           ${ISOFW} --bus socketcand:127.0.0.1:9 --param vt=maybe)
  add_test(NAME isobus_vt_cli_bad_defect COMMAND sh ${CLI} 2 "parameter 'vt_defect' must be one of"
           ${ISOFW} --bus socketcand:127.0.0.1:9 --param vt=yes --param vt_defect=lazy)
  add_test(NAME isobus_vt_cli_defect_needs_vt
           COMMAND sh ${CLI} 2 "vt_defect needs the operator interface (vt=yes)"
           ${ISOFW} --bus socketcand:127.0.0.1:9 --param vt_defect=no-alarm)
  add_test(NAME isobus_vt_cli_params_accepted
           COMMAND sh ${CLI} 1 "127.0.0.1:9" ${ISOFW} --bus socketcand:127.0.0.1:9
                   --param vt=yes --param vt_defect=bad-pool)
endif()
