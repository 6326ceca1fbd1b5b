"""
A rosbag2-layout MCAP recording: ``BAG/metadata.yaml`` and ``BAG/BAG_0.mcap``, as ros2 bag.

Written with the ``mcap`` library: profile ``ros2``, every channel's messages CDR as they came
off the wire (nothing re-serialised), every schema the complete ``ros2msg`` definition of its
type (the type's .msg text, then each type it uses after a line of 80 ``=`` and
``MSG: pkg/msg/Type``, as rosbag2 embeds them), so that rosbag2, rosbags, Foxglove and
``mcap_ros2``'s decoder read a file without the package's messages installed. ``metadata.yaml``
is rosbag2's (version 8, storage mcap) and is written when the recording closes.

``check_bag_path`` says what is wrong with a recording path before anything starts.
"""

from __future__ import annotations

import os
import re

from ament_index_python.packages import get_package_share_directory, PackageNotFoundError
from mcap.writer import CompressionType, Writer
from mover6_control.errors import InvalidInputError
import yaml

SEPARATOR = '=' * 80
PRIMITIVES = frozenset((
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16', 'int32',
    'uint32', 'int64', 'uint64', 'string', 'wstring', 'time', 'duration'))
METADATA_VERSION = 8          # rosbag2's in Jazzy


def check_bag_path(path: str) -> str:
    """
    Return the absolute recording folder ``path``, or raise ``InvalidInputError`` saying why not.

    As ros2 bag: the folder must not exist yet (a recording never overwrites one), and the
    folder it goes into must exist and be writable.
    """
    if not path or not path.strip():
        raise InvalidInputError('recording path is empty')
    path = os.path.abspath(path)
    if os.path.exists(path):
        raise InvalidInputError(f'recording path {path} already exists: give a new folder')
    parent = os.path.dirname(path)
    if os.path.exists(parent) and not os.path.isdir(parent):
        raise InvalidInputError(f'recording path {path}: {parent} is not a folder')
    if not os.path.isdir(parent):
        raise InvalidInputError(f'recording path {path}: its folder {parent} does not exist')
    if not os.access(parent, os.W_OK | os.X_OK):
        raise InvalidInputError(f'recording path {path}: its folder {parent} is not writable')
    return path


def _msg_file(type_name: str) -> str:
    """Return the text of the .msg file of ``pkg/msg/Type`` (installed with its package)."""
    package, kind, name = type_name.split('/')
    try:
        share = get_package_share_directory(package)
    except (PackageNotFoundError, OSError):      # OSError: no AMENT_PREFIX_PATH at all
        raise InvalidInputError(f'no definition of {type_name}: {package} not found') from None
    path = os.path.join(share, kind, name + '.msg')
    if not os.path.isfile(path):
        raise InvalidInputError(f'no definition of {type_name}: {path} not found')
    with open(path) as f:
        return f.read()


def _field_types(text: str, package: str) -> list:
    """Return the message types ``pkg/msg/Type`` the fields of a .msg ``text`` use."""
    out = []
    for line in text.splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        base = re.split(r'[\[<]', line.split()[0], maxsplit=1)[0]
        if base in PRIMITIVES:
            continue
        if '/' not in base:
            base = f'{package}/{base}'
        parts = base.split('/')
        out.append(f'{parts[0]}/msg/{parts[-1]}')
    return out


def message_definition(type_name: str) -> str:
    """Return the complete ``ros2msg`` definition of ``type_name`` (``pkg/msg/Type``)."""
    text = _msg_file(type_name)
    parts = [text.rstrip('\n')]
    seen = {type_name}
    queue = _field_types(text, type_name.split('/')[0])
    while queue:
        dep = queue.pop(0)
        if dep in seen:
            continue
        seen.add(dep)
        dep_text = _msg_file(dep)
        parts.append(f'{SEPARATOR}\nMSG: {dep}\n{dep_text.rstrip(chr(10))}')
        queue += _field_types(dep_text, dep.split('/')[0])
    return '\n'.join(parts) + '\n'


class BagWriter:
    """One rosbag2 MCAP recording; ``add_topic``, then ``write``, then ``close`` once."""

    def __init__(self, path: str):
        self.path = check_bag_path(path)
        os.mkdir(self.path)
        self.file_name = os.path.basename(self.path) + '_0.mcap'
        self._file = open(os.path.join(self.path, self.file_name), 'wb')
        self._writer = Writer(self._file, compression=CompressionType.ZSTD)
        self._writer.start(profile='ros2', library='mover6_control recorder (mcap-python)')
        self._schemas = {}
        self.topics = {}         # name -> {'type', 'qos', 'channel', 'count'}
        self.first = None
        self.last = None
        self.closed = False

    def add_topic(self, name: str, type_name: str, qos: str = '') -> int:
        """Register topic ``name`` of ``type_name`` (``offered_qos_profiles`` text ``qos``)."""
        if name in self.topics:
            return self.topics[name]['channel']
        if type_name not in self._schemas:
            self._schemas[type_name] = self._writer.register_schema(
                name=type_name, encoding='ros2msg',
                data=message_definition(type_name).encode())
        channel = self._writer.register_channel(
            topic=name, message_encoding='cdr', schema_id=self._schemas[type_name],
            metadata={'offered_qos_profiles': qos})
        self.topics[name] = {'type': type_name, 'qos': qos, 'channel': channel, 'count': 0}
        return channel

    def write(self, name: str, data: bytes, time_ns: int) -> None:
        """Write one serialized message of topic ``name`` received at ``time_ns`` [ns]."""
        topic = self.topics[name]
        self._writer.add_message(channel_id=topic['channel'], log_time=time_ns, data=data,
                                 publish_time=time_ns, sequence=topic['count'])
        topic['count'] += 1
        self.first = time_ns if self.first is None else min(self.first, time_ns)
        self.last = time_ns if self.last is None else max(self.last, time_ns)

    @property
    def message_count(self) -> int:
        """Return the number of messages written."""
        return sum(t['count'] for t in self.topics.values())

    def metadata(self) -> dict:
        """Return rosbag2's ``metadata.yaml`` content of this recording."""
        start = self.first or 0
        duration = (self.last - self.first) if self.first is not None else 0
        count = self.message_count
        return {'rosbag2_bagfile_information': {
            'version': METADATA_VERSION,
            'storage_identifier': 'mcap',
            'duration': {'nanoseconds': duration},
            'starting_time': {'nanoseconds_since_epoch': start},
            'message_count': count,
            'topics_with_message_count': [
                {'topic_metadata': {'name': name, 'type': t['type'],
                                    'serialization_format': 'cdr',
                                    'offered_qos_profiles': t['qos'],
                                    'type_description_hash': ''},
                 'message_count': t['count']}
                for name, t in self.topics.items()],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [self.file_name],
            'files': [{'path': self.file_name,
                       'starting_time': {'nanoseconds_since_epoch': start},
                       'duration': {'nanoseconds': duration},
                       'message_count': count}],
            'custom_data': {},
            'ros_distro': 'jazzy',
        }}

    def close(self) -> None:
        """
        Finish the MCAP file (summary, index) and write metadata.yaml; only the first call acts.

        Raises ``OSError`` when the disk refuses (the file is closed all the same).
        """
        if self.closed:
            return
        self.closed = True
        try:
            self._writer.finish()
        finally:
            self._file.close()
        with open(os.path.join(self.path, 'metadata.yaml'), 'w') as f:
            yaml.safe_dump(self.metadata(), f, sort_keys=False)
