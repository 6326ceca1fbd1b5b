"""The DDS transport choice of the controller and the bridge (nodes/dds_transport.py)."""

import os
import re

from mover6_control.nodes import dds_transport
import pytest

PREFIX = re.compile(r'^01\.0f(\.[0-9a-f]{2}){10}$')


def test_prefix_is_eprosima_vendor_random_host_pid_and_instance():
    prefix = dds_transport.guid_prefix(0x12345678, host=b'\xbe\xef', instance=b'\x01\x02\x03\x04')
    assert prefix == '01.0f.be.ef.78.56.34.12.01.02.03.04'
    one, two = dds_transport.guid_prefix(7), dds_transport.guid_prefix(7)
    assert PREFIX.match(one) and PREFIX.match(two)
    assert one != two                 # random host and instance bytes


def test_writes_a_default_profile_with_a_prefix_and_names_it(tmp_path, monkeypatch):
    monkeypatch.setattr(dds_transport.tempfile, 'tempdir', str(tmp_path))
    env = {}
    note = dds_transport.use_udp_between_processes(env)
    path = env[dds_transport.PROFILE_ENVS[0]]
    assert os.path.dirname(path) == str(tmp_path)
    with open(path) as f:
        xml = f.read()
    assert 'is_default_profile="true"' in xml
    prefix = re.search(r'<prefix>(.*)</prefix>', xml).group(1)
    assert PREFIX.match(prefix)
    assert prefix.split('.')[4:8] == [f'{b:02x}' for b in os.getpid().to_bytes(4, 'little')]
    assert 'UDP' in note and dds_transport.KEEP_ENV in note


@pytest.mark.parametrize('env, said', [
    ({dds_transport.KEEP_ENV: '1'}, 'shared memory kept'),
    ({'RMW_IMPLEMENTATION': 'rmw_cyclonedds_cpp'}, 'left as they are'),
    ({'FASTRTPS_DEFAULT_PROFILES_FILE': '/etc/mine.xml'}, 'its profile is used'),
    ({'FASTDDS_DEFAULT_PROFILES_FILE': '/etc/mine.xml'}, 'its profile is used'),
])
def test_leaves_fast_dds_alone_when_told_or_configured(env, said):
    before = dict(env)
    assert said in dds_transport.use_udp_between_processes(env)
    assert env == before              # nothing written, nothing set
