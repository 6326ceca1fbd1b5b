"""The end-to-end tests' use of the driver: its ~/reset and ~/enable, and its bus status."""

from std_srvs.srv import Trigger

SERVICES = ('reset', 'enable')


def add_driver_services(node):
    """Give ``node`` (a GoalClient) clients of the driver's ~/reset and ~/enable."""
    node.driver_services = {kind: node.create_client(Trigger, f'driver/{kind}')
                            for kind in SERVICES}


def bus(client):
    """Return the driver's bus status values (empty before the first)."""
    return client.diagnostics.get('driver: bus', {})


def call(client, kind):
    """Call the driver's ~/``kind`` and return the response."""
    service = client.driver_services[kind]
    assert service.wait_for_service(10.0), kind
    future = service.call_async(Trigger.Request())
    assert client.spin_until(future.done, 30.0), kind
    return future.result()
