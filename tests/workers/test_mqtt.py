"""The server's MQTT clients (`workers.mqtt`) against the real broker."""

import socket
import threading

from django.conf import settings

from workers.mqtt import new_client


def test_a_server_client_sends_every_packet_at_once() -> None:
    client = new_client("test")
    connected = threading.Event()
    client.on_connect = lambda *args: connected.set()
    client.connect(settings.MQTT_HOST, settings.MQTT_PORT)
    client.loop_start()
    try:
        assert connected.wait(10)
        # Without TCP_NODELAY a small message waits for the ACK of the previous one (up to 40 ms).
        assert client.socket().getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY) == 1
    finally:
        client.disconnect()
        client.loop_stop()
