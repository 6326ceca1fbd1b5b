# shellcheck shell=bash
# ./run.sh test [pytest args]: colcon test in a private network namespace when the machine allows
# one (the whole suite: then the host_network tests again on the host network), the results and
# the skip budget (sourced by run.sh; .ci/run calls ./run.sh test).

run_tests() {
    # Inside a private network namespace (only loopback) when the machine allows one: then
    # nothing a test sends can reach another process or machine, and the tests run the
    # package's local DDS configuration (test/e2e/test_local_dds.py checks that they did).
    if [ "${MOVER6_TEST_NETWORK:-}" = netns ]; then
        enter_test_netns
    else
        # Without one: the same local configuration on the host network (loopback only),
        # unless the user chose their own (ROS_AUTOMATIC_DISCOVERY_RANGE, MOVER6_DDS=...).
        # Everything installed first, here: inside the namespace no registry can be reached.
        ensure
        setup_browser
        if [ "${MOVER6_NETNS:-1}" != 0 ] && private_netns; then
            test_in_netns_then_host "$@"
        fi
        if [ "${MOVER6_NETNS:-1}" = 0 ]; then
            log 'MOVER6_NETNS=0: tests on the host network (the local configuration: loopback only)'
        else
            log 'this machine allows no private network namespace: tests on the host network'
        fi
        export MOVER6_TEST_NETWORK=host
    fi
    pick_domain_id
    log "tests in ROS_DOMAIN_ID=$ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE=${ROS_AUTOMATIC_DISCOVERY_RANGE:-}${MOVER6_DDS:+, MOVER6_DDS=$MOVER6_DDS}"
    colcon_test "$@"
    test_results
}

enter_test_netns() {
    # Inside the namespace run.sh made: only lo, brought up; the user's DDS variables dropped.
    only_loopback || { log 'MOVER6_TEST_NETWORK=netns, but interfaces other than lo exist'; exit 1; }
    ip link set lo up
    unset ROS_AUTOMATIC_DISCOVERY_RANGE FASTRTPS_DEFAULT_PROFILES_FILE \
        FASTDDS_DEFAULT_PROFILES_FILE FASTDDS_BUILTIN_TRANSPORTS ROS_LOCALHOST_ONLY \
        ROS_STATIC_PEERS MOVER6_DDS
    ensure
}

test_in_netns_then_host() {
    # With pytest arguments: only those, in the namespace. The whole suite: then the tests of
    # the DDS configuration itself (marker host_network) again on this machine's own network,
    # where a user runs the launchers: the local configuration keeps every socket on loopback
    # there too. Exits with the runs' result.
    log "tests inside a private network namespace (${UNSHARE[*]}): only loopback (MOVER6_NETNS=0: host)"
    [ $# -gt 0 ] && MOVER6_TEST_NETWORK=netns exec "${UNSHARE[@]}" "$ROOT/run.sh" test "$@"
    local netns_rc=0 host_rc=0
    MOVER6_TEST_NETWORK=netns "${UNSHARE[@]}" "$ROOT/run.sh" test || netns_rc=$?
    local verdict
    verdict=$(cat "$WS/skips.txt" 2>/dev/null || echo 'the skips were not judged')
    log 'the host_network tests again on the host network (the local configuration)'
    MOVER6_NETNS=0 "$ROOT/run.sh" test -m host_network || host_rc=$?
    log "inside the namespace: exit $netns_rc; on the host network: exit $host_rc"
    # The last line: the verdict on the skips of the whole suite's run (the namespace's).
    log "$verdict"
    exit $(( netns_rc != 0 || host_rc != 0 ))
}

colcon_test() {
    # Bytecode, and pytest's rewritten test modules, cached in the workspace (out of the
    # source tree): without it every run compiled every module again, a large part of the
    # unit tier's time. Python checks each source's mtime, so a cache is never stale. For
    # pytest's process only: test/conftest.py takes it from the processes the tests start.
    unset PYTHONDONTWRITEBYTECODE
    export PYTHONPYCACHEPREFIX="$WS/pycache"
    # No stale results: a run that wrote none must fail, not pass on the last one's.
    rm -rf "$WS/build/mover6_control/test_results" "$WS/build/mover6_control/pytest.xml" \
        "$WS/skips.txt"
    (cd "$ROOT" && colcon --log-base "$WS/log" test --base-paths . \
        --build-base "$WS/build" --install-base "$WS/install" \
        --packages-select mover6_control --event-handlers console_direct+ summary- \
        --pytest-args "$@") || true
}

test_results() {
    # The results (exit 1 when any test failed or none ran), then the skips that say so: every
    # skipped or xfailed test with its reason; one that test/skips_allowed.json does not list by
    # name fails the run (the browser tests' only with MOVER6_SKIP_BROWSER=1). The last line
    # says whether the skips let the run count green.
    if [ ! -f "$WS/build/mover6_control/pytest.xml" ]; then
        log "pytest wrote no results: the test run did not happen (see $WS/log)"
        exit 1
    fi
    local rc=0
    colcon test-result --test-result-base "$WS/build/mover6_control" --verbose || rc=$?
    python "$ROOT/test/skip_budget.py" --summary "$WS/skips.txt" \
        "$WS/build/mover6_control/pytest.xml" || rc=1
    exit "$rc"
}
