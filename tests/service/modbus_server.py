"""A real pymodbus server playing the rig's PLC (register map of docs): TCP on loopback, or
RTU on a serial device — one end of :class:`NullModem`, a pair of pseudo-terminals joined
like a null-modem cable (the driver opens the other end)."""

import asyncio
import os
import select
import socket
import termios
import threading
import tty

from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from rigd_drivers.modbus.driver import float_to_regs, regs_to_float


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class NullModem:
    """Two pseudo-terminal pairs whose master sides are joined by a relay thread: a serial
    cable between the device paths :attr:`a` and :attr:`b` (what ``socat pty pty`` does).

    :meth:`unplug` cuts the cable (bytes either way are lost, as on a dead RS-485 line);
    :meth:`plug` reconnects it, dropping whatever was queued meanwhile.
    """

    def __init__(self):
        self._ma, self._sa = os.openpty()
        self._mb, self._sb = os.openpty()
        for fd in (self._sa, self._sb):   # the slaves stay open here too: no EIO on the
            tty.setraw(fd)                # masters while neither end has its device open
        self.a = os.ttyname(self._sa)
        self.b = os.ttyname(self._sb)
        self.connected = True
        self.bytes = 0
        self._stop_r, self._stop_w = os.pipe()
        self._thread = threading.Thread(target=self._relay, daemon=True)
        self._thread.start()

    def _relay(self):
        peer = {self._ma: self._mb, self._mb: self._ma}
        while True:
            ready, _, _ = select.select([self._ma, self._mb, self._stop_r], [], [])
            if self._stop_r in ready:
                return
            for fd in ready:
                try:
                    data = os.read(fd, 4096)
                except OSError:
                    continue
                if self.connected and data:
                    os.write(peer[fd], data)
                    self.bytes += len(data)

    def unplug(self):
        self.connected = False

    def plug(self):
        for fd in (self._sa, self._sb):
            termios.tcflush(fd, termios.TCIOFLUSH)
        self.connected = True

    def close(self):
        os.write(self._stop_w, b"x")
        self._thread.join(5)
        for fd in (self._ma, self._mb, self._sa, self._sb, self._stop_r, self._stop_w):
            os.close(fd)


class PlcServer:
    """The PLC. ``first_delay_s``: the first read is answered that late (a device slow to
    answer after a connect); ``first_until``: the first read is answered once this callable
    returns true (an event of the test, e.g. the driver has counted the timeout), not after a
    guess of a time. While :attr:`hold` is true every read waits (:attr:`waiting` counts the
    reads held): a PLC that has taken a request and not answered yet."""

    def __init__(self, port=None, p_inj_bar=4.0, omega_rpm=3000.0, status=0, device=None,
                 baudrate=19200, parity="E", first_delay_s=0.0, first_until=None):
        self.device = device            # RTU on this serial device; TCP on loopback if None
        self.first_delay_s = first_delay_s
        self.first_until = first_until
        self.hold = False
        self.waiting = 0
        self._first_done = False
        self.serial = {"baudrate": baudrate, "parity": parity}
        self.port = None if device else (port or free_port())
        self.values = {"p_inj_bar": p_inj_bar, "omega_rpm": omega_rpm, "status": status}
        self.setpoints = {}
        self.reads = 0
        self._loop = None
        self._srv = None
        self._thread = None

    async def _action(self, fc, start, address, count, regs, set_values):
        regs[0 - start:2 - start] = float_to_regs(self.values["p_inj_bar"])
        regs[2 - start:4 - start] = float_to_regs(self.values["omega_rpm"])
        regs[4 - start] = self.values["status"]
        if fc == 4:
            if not self._first_done:
                self._first_done = True          # only the very first read request
                if self.first_delay_s:
                    await asyncio.sleep(self.first_delay_s)
                while self.first_until is not None and not self.first_until():
                    await asyncio.sleep(0.005)
            self.waiting += 1
            while self.hold:
                await asyncio.sleep(0.005)
            self.waiting -= 1
            self.reads += 1
        if set_values is not None:
            for name, addr in (("p_inj_bar", 100), ("omega_rpm", 102)):
                if address <= addr < address + count - 1:
                    self.setpoints[name] = regs_to_float(set_values[addr - address:
                                                                    addr - address + 2])
        return None

    def start(self):
        ready = threading.Event()

        def run():
            async def main():
                self._loop = asyncio.get_running_loop()
                dev = SimDevice(1, simdata=[SimData(0, count=200, values=0,
                                                    datatype=DataType.REGISTERS)],
                                action=self._action)
                if self.device:
                    self._srv = ModbusSerialServer(dev, port=self.device, **self.serial)
                else:
                    self._srv = ModbusTcpServer(dev, address=("127.0.0.1", self.port))
                task = asyncio.ensure_future(self._srv.serve_forever())
                for _ in range(100):
                    await asyncio.sleep(0.01)
                    if self._srv.is_active():
                        break
                ready.set()
                await task
            asyncio.run(main())

        self._thread = threading.Thread(target=run, daemon=True)
        self._thread.start()
        ready.wait(5)
        return self

    def stop(self):
        if self._loop is not None:
            asyncio.run_coroutine_threadsafe(self._srv.shutdown(), self._loop).result(5)
            self._thread.join(5)
            self._loop = None
