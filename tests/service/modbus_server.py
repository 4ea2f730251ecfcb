"""A real pymodbus TCP server on loopback playing the rig's PLC (register map of docs)."""

import asyncio
import socket
import threading

from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from rigd_drivers.modbus import float_to_regs, regs_to_float


def free_port():
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class PlcServer:
    def __init__(self, port=None, p_inj_bar=4.0, omega_rpm=3000.0, status=0):
        self.port = port or free_port()
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
