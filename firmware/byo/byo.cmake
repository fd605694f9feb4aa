# The fertilizer controller built against a foreign database (issue 28): the RateMaster RC-400's
# layout (docs/examples/byo-fertilizer/ratemaster_rc400.dbc). Its bus layer is generated from
# that database by cantools (generate.sh -> generated/); the control core and the app loop are
# the reference firmware's, unchanged. Included from ../CMakeLists.txt after include(CTest).
set(BYO_DIR ${CMAKE_CURRENT_LIST_DIR})

# The tests of a replay program (tests/replay.h): <prefix>_vectors replays the files; the replay
# must see a difference (<prefix>_vectors_detect_mismatch: the first file with the first
# "out <id> s" line whose data matches <data_regex> given the first byte <byte>) and a missing
# file (<prefix>_vectors_detect_missing_file).
function(byo_replay_tests prefix replay id data_regex byte)
  set(expect ${CMAKE_CURRENT_SOURCE_DIR}/tests/expect_exit.sh)
  add_test(NAME ${prefix}_vectors COMMAND ${replay} ${ARGN})
  list(GET ARGN 0 first_file)
  file(READ ${first_file} text)
  string(REGEX MATCH "\nout ${id} s ${data_regex}\n" line "${text}")
  string(LENGTH "\nout ${id} s " skip)
  string(SUBSTRING "${line}" ${skip} 2 old)
  string(REPLACE "out ${id} s ${old}" "out ${id} s ${byte}" wrong "${line}")
  string(FIND "${text}" "${line}" at)
  string(SUBSTRING "${text}" 0 ${at} head)
  string(LENGTH "${line}" len)
  math(EXPR tail_at "${at} + ${len}")
  string(SUBSTRING "${text}" ${tail_at} -1 tail)
  file(WRITE ${CMAKE_CURRENT_BINARY_DIR}/${prefix}-wrong.txt "${head}${wrong}${tail}")
  add_test(NAME ${prefix}_vectors_detect_mismatch
           COMMAND sh ${expect} 1 "the Python build ${id} s ${byte}" $<TARGET_FILE:${replay}>
                   ${CMAKE_CURRENT_BINARY_DIR}/${prefix}-wrong.txt)
  add_test(NAME ${prefix}_vectors_detect_missing_file
           COMMAND sh ${expect} 1 "no-such.txt: missing" $<TARGET_FILE:${replay}> no-such.txt)
endfunction()

# One controller on a foreign database: its bus layer (agrihil_byo_<short>: the adapter and the
# code generated from its database), its program, and when testing the adapter's unit tests
# (test_<short>_adapter, ctest <short>_adapter) and its replay program (replay_<short>).
function(byo_controller short program adapter generated main)
  add_library(agrihil_byo_${short} STATIC ${BYO_DIR}/${adapter}
              ${BYO_DIR}/generated/${generated})
  target_include_directories(agrihil_byo_${short} PUBLIC ${BYO_DIR} ${BYO_DIR}/generated
                             ${CMAKE_CURRENT_SOURCE_DIR}/hal)
  target_link_libraries(agrihil_byo_${short} PUBLIC agrihil_core)
  add_executable(${program} ${BYO_DIR}/${main})
  target_link_libraries(${program} PRIVATE agrihil_byo_${short} agrihil_app)
  if(BUILD_TESTING)
    add_executable(test_${short}_adapter ${BYO_DIR}/tests/test_${short}_adapter.c)
    target_include_directories(test_${short}_adapter PRIVATE ${CMAKE_CURRENT_SOURCE_DIR}/tests)
    target_link_libraries(test_${short}_adapter PRIVATE agrihil_byo_${short})
    add_test(NAME ${short}_adapter COMMAND test_${short}_adapter)
    add_executable(replay_${short} ${BYO_DIR}/tests/replay_${short}.c ${BYO_DIR}/tests/replay.c)
    target_link_libraries(replay_${short} PRIVATE agrihil_byo_${short})
  endif()
endfunction()

# the RC-400's frames, packed and unpacked by code generated from its own database
byo_controller(rc400 agrihil-fertilizer-rc400-fw fertilizer_rc400_adapter.c ratemaster_rc400.c
               fertilizer_rc400_main.c)

if(BUILD_TESTING)
  # the Python build's frames (tests/make_vectors.py from dbc_adapter.py), byte for byte
  set(RC400_VECTORS ${BYO_DIR}/tests/data/rc400-physical.txt
      ${BYO_DIR}/tests/data/rc400-paper-literal.txt ${BYO_DIR}/tests/data/rc400-open-loop.txt)
  # a changed byte: the physical vectors' first nonzero drive command with its first byte ff
  byo_replay_tests(rc400 replay_rc400 220 "[0-9a-f]*[1-9a-f][0-9a-f]*" ff ${RC400_VECTORS})

  # the command line is agrihil-fertilizer-fw's
  set(RC400_FW $<TARGET_FILE:agrihil-fertilizer-rc400-fw>)
  set(RC400_CLI ${CMAKE_CURRENT_SOURCE_DIR}/tests/expect_exit.sh)
  add_test(NAME rc400_cli_unknown_param COMMAND sh ${RC400_CLI} 2 "unknown parameter 'kp9'"
           ${RC400_FW} --bus socketcand:127.0.0.1:9 --param kp9=1)
  add_test(NAME rc400_cli_law_contradiction COMMAND sh ${RC400_CLI} 2
           "contradicts --law physical"
           ${RC400_FW} --bus socketcand:127.0.0.1:9 --law physical --param mode=open-loop)
  add_test(NAME rc400_cli_open_loop_rejects_gains COMMAND sh ${RC400_CLI} 2
           "unknown parameter 'ki1'"
           ${RC400_FW} --bus socketcand:127.0.0.1:9 --law open-loop --param ki1=0.5)
  add_test(NAME rc400_cli_connection_refused COMMAND sh ${RC400_CLI} 1 "127.0.0.1:9"
           ${RC400_FW} --bus socketcand:127.0.0.1:9 --param mode=physical --param ff_coeff=4.39)
  add_test(NAME rc400_cli_help COMMAND sh ${RC400_CLI} 0 "agrihil-fertilizer-rc400-fw"
           ${RC400_FW} --help)
endif()

# The depth controller built against a foreign database (issue 28): the DepthPro DP-200's
# layout (docs/examples/byo-depth/depthpro_dp200.dbc), its bus layer generated from that
# database by cantools (generate.sh -> generated/); the control core (fuzzy PID, roller hold)
# is the reference firmware's, unchanged. At boot it remaps the drive's PDOs by SDO.
byo_controller(dp200 agrihil-depth-dp200-fw depth_dp200_adapter.c depthpro_dp200.c
               depth_dp200_main.c)

if(BUILD_TESTING)
  # the Python build's frames (tests/make_vectors_dp200.py from dbc_adapter.py), byte for byte
  set(DP200_VECTORS ${BYO_DIR}/tests/data-dp200/dp200-profile.txt
      ${BYO_DIR}/tests/data-dp200/dp200-defaults.txt ${BYO_DIR}/tests/data-dp200/dp200-refused.txt)
  # a changed byte: the profile vectors' first target velocity with a nonzero first byte, 00
  byo_replay_tests(dp200 replay_dp200 302 "[1-9a-f][0-9a-f]*" 00 ${DP200_VECTORS})

  # the command line is agrihil-depth-fw's
  set(DP200_FW $<TARGET_FILE:agrihil-depth-dp200-fw>)
  set(DP200_CLI ${CMAKE_CURRENT_SOURCE_DIR}/tests/expect_exit.sh)
  add_test(NAME dp200_cli_unknown_param COMMAND sh ${DP200_CLI} 2 "unknown parameter 'kp9'"
           ${DP200_FW} --bus socketcand:127.0.0.1:9 --param kp9=1)
  add_test(NAME dp200_cli_bad_timeout COMMAND sh ${DP200_CLI} 2 "sdo_timeout_s must be > 0"
           ${DP200_FW} --bus socketcand:127.0.0.1:9 --param sdo_timeout_s=0)
  add_test(NAME dp200_cli_connection_refused COMMAND sh ${DP200_CLI} 1 "127.0.0.1:9"
           ${DP200_FW} --bus socketcand:127.0.0.1:9 --param kp0=3)
  add_test(NAME dp200_cli_help COMMAND sh ${DP200_CLI} 0 "agrihil-depth-dp200-fw"
           ${DP200_FW} --help)
endif()
