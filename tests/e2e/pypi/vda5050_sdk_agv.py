"""A vehicle of PyPI vda5050-sdk (the version installed in the interpreter running this), for
tests/e2e/test_order_stall.py: the library's own VehicleClient over MQTT, each order run by its reference
OrderExecutor, every line of it unmodified; each order in a task of its own, so that it hears instant
actions (cancelOrder) while it drives. Executors `per-order`: a new one for each order (and update),
as the library's FakeAgv runs them; `one`: the vehicle's one executor runs every order, which fails inside
on an update that arrives while it runs (`cannot transition from COMPLETED to VERIFYING_ARRIVAL`) and stands
still with no error reported (issue #43).

Usage: python vda5050_sdk_agv.py <mqtt url> <manufacturer> <serialNumber> <version> <x> <y> <node seconds>
<per-order|one>
Runs until SIGTERM; states every second so that the fleet sees it online while it stands still. Runs in
its own environment: the library's top-level package is named `vda5050`, as ours is."""

import asyncio
import signal
import sys

from vda5050.client.agv.executor import OrderExecutor
from vda5050.domain.execution.policy import ArrivalToleranceDefaults

from vda5050 import VehicleClient, VehicleConfig


async def main(
    broker_url: str, manufacturer: str, serial: str, version: str, x: str, y: str, node: str, executors: str
) -> None:
    config = VehicleConfig(
        broker_url=broker_url,
        manufacturer=manufacturer,
        serial_number=serial,
        protocol_version=version,
        state_interval=1.0,
    )
    client = VehicleClient(config)

    def new_executor() -> OrderExecutor:
        return OrderExecutor(
            client.publisher,
            node_delay=float(node),
            arrival_defaults=ArrivalToleranceDefaults(
                tolerance_xy=config.arrival_xy_tolerance,
                tolerance_theta=config.arrival_theta_tolerance,
                timeout=config.arrival_timeout,
            ),
        )

    the_one: list[OrderExecutor] = []
    running: set[asyncio.Task] = set()

    async def take(order) -> None:
        """Each order runs in a task of its own: the client hears instant actions (cancelOrder) meanwhile."""
        task = asyncio.create_task(run(order))
        running.add(task)
        task.add_done_callback(running.discard)

    async def run(order) -> None:
        if executors == "per-order":
            executor = new_executor()
        else:
            the_one[:] = the_one or [new_executor()]
            executor = the_one[0]
        try:
            print(
                "order", order.order_id, order.order_update_id, "ended", await executor.run(order), flush=True
            )
        except Exception as exc:  # the library's own failure, shown in the test's output
            print("order", order.order_id, order.order_update_id, "raised", repr(exc), flush=True)

    client.on_order(take)
    await client.connect()
    client.publisher.update_position(x=float(x), y=float(y), theta=0.0, map_id="map")
    await client.publish_state()
    print(f"vda5050-sdk AGV {serial} started", flush=True)
    stopped = asyncio.Event()
    asyncio.get_running_loop().add_signal_handler(signal.SIGTERM, stopped.set)
    await stopped.wait()
    await client.disconnect()


if __name__ == "__main__":
    asyncio.run(main(*sys.argv[1:]))
