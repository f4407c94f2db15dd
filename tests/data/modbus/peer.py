#!/usr/bin/python3
"""Modbus TCP peers that are not Cellwright's code, for the tests of the Modbus client (drivers/modbus) and server
(emulate/modbus_server). Run with Debian's /usr/bin/python3 (python3-pymodbus 3.0.0). Each mode listens or connects on
loopback, prints one line "port N" (servers) or "ready" (the client) on stdout, then reads commands from stdin, one a
line, and answers each with one line on stdout. It ends when stdin closes.

  peer.py server        pymodbus's TCP server, unit 1, on 127.0.0.1 (a free port). Coils 0..15 start as
                        1,0,1,0,0..., discrete inputs 0..15 as 1,0,1,1,0,0,1,0,0...; other addresses are refused
                        (exception 2). Commands:
                          exception CODE   the next request is answered with exception CODE   -> "ok"
                          drop             the next request closes the connection unanswered  -> "ok"
                          input ADDR 0|1   sets a discrete input                               -> "ok"
                          coil ADDR        what the coil holds                                -> "coil ADDR 0|1"
                          requests         requests answered so far                           -> "requests N"
  peer.py junk          a raw TCP server that answers every read with 40 bytes of junk.
  peer.py silent        a raw TCP server that accepts and reads, and never answers.
  peer.py late SECONDS  a raw TCP server that answers its first request SECONDS late (then prints "late answer
                        sent") and every later one at once: reads with inputs 1,0,1,1,0..., writes echoed.
  peer.py client PORT [UNIT]
                        pymodbus's TCP client (timeout 3 s) connected to 127.0.0.1:PORT. Commands:
                          read_coils A N | read_inputs A N | read_holding A N | write_coil A 0|1 |
                          write_coils A V,V,...  -> "ok" followed by the bits read (reads), "exception CODE", or
                                                    "error TEXT" (no valid answer)
  peer.py plc PORT MAX_SCANS
                        a PLC program on pymodbus's TCP client (unit 1), for virtual commissioning against the twin
                        (`twin emulate --scenario ... --io`): runs the input conveyor (coil 0 on), then scans: reads
                        discrete inputs 0..3 until input 0 (the input conveyor's photo-eye) is on, at most MAX_SCANS
                        times; then stops the belt (coil 0 off) and reads coils 0..2. Prints "ready", one line per
                        reply ("SCAN TID PDU": the scan it came in, the transaction id, the reply's PDU in hex as
                        pymodbus encodes it), then "eye at scan N" (or "no eye in MAX_SCANS scans"), then "end".
"""
import asyncio
import logging
import socket
import sys
import threading
import time

logging.disable(logging.CRITICAL)  # pymodbus logs refused requests; the tests read only our own lines


def say(line):
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


def run_pymodbus_server():
    from pymodbus.datastore import ModbusSequentialDataBlock, ModbusServerContext, ModbusSlaveContext
    from pymodbus.pdu import ExceptionResponse
    from pymodbus.server.async_io import ModbusTcpServer

    coils = [1, 0, 1] + [0] * 13
    inputs = [1, 0, 1, 1, 0, 0, 1, 0] + [0] * 8
    unit = ModbusSlaveContext(di=ModbusSequentialDataBlock(0, inputs), co=ModbusSequentialDataBlock(0, coils),
                              hr=ModbusSequentialDataBlock(0, [0] * 16), ir=ModbusSequentialDataBlock(0, [0] * 16),
                              zero_mode=True)
    context = ModbusServerContext(slaves=unit, single=True)
    state = {"exception": None, "drop": False, "requests": 0}
    holder = {}

    def manipulate(response):
        state["requests"] += 1
        if state["drop"]:
            state["drop"] = False
            for connection in list(holder["server"].active_connections.values()):
                connection.transport.abort()
            return response, False
        if state["exception"] is not None:
            refused = ExceptionResponse(response.function_code & 0x7F, state["exception"])
            refused.transaction_id = response.transaction_id
            refused.unit_id = response.unit_id
            state["exception"] = None
            return refused, False
        return response, False

    async def main():
        loop = asyncio.get_running_loop()
        server = ModbusTcpServer(context, address=("127.0.0.1", 0), response_manipulator=manipulate, loop=loop)
        holder["server"] = server
        task = asyncio.create_task(server.serve_forever())
        await server.serving
        say("port %d" % server.server.sockets[0].getsockname()[1])
        while True:
            line = await loop.run_in_executor(None, sys.stdin.readline)
            if not line:
                break
            words = line.split()
            if not words:
                continue
            if words[0] == "exception":
                state["exception"] = int(words[1])
                say("ok")
            elif words[0] == "drop":
                state["drop"] = True
                say("ok")
            elif words[0] == "input":
                unit.setValues(2, int(words[1]), [int(words[2])])
                say("ok")
            elif words[0] == "coil":
                say("coil %s %d" % (words[1], 1 if unit.getValues(1, int(words[1]), 1)[0] else 0))
            elif words[0] == "requests":
                say("requests %d" % state["requests"])
            else:
                say("error unknown command " + words[0])
        task.cancel()

    asyncio.run(main())


def reply_to(request):
    """A valid answer to a read (function 1 or 2: bits 1,0,1,1 then zeros) or a write of one coil (echoed)."""
    function = request[7]
    if function in (1, 2):
        count = (request[10] << 8) | request[11]
        data = bytes([0x0D] + [0] * ((count + 7) // 8 - 1))
        pdu = bytes([function, len(data)]) + data
    else:
        pdu = request[7:12]
    return request[0:4] + bytes([0, len(pdu) + 1, request[6]]) + pdu


def run_raw_server(answer, late=None):
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    listener.bind(("127.0.0.1", 0))
    listener.listen(8)
    say("port %d" % listener.getsockname()[1])

    first = [True]

    def serve(connection):
        with connection:
            while True:
                data = connection.recv(260)
                if not data:
                    return
                if late is not None:
                    if first[0]:
                        first[0] = False
                        time.sleep(late)
                        connection.sendall(reply_to(data))
                        say("late answer sent")
                    else:
                        connection.sendall(reply_to(data))
                elif answer:
                    connection.sendall(bytes((0x5A + i * 37) & 0xFF for i in range(40)))

    def accept():
        while True:
            connection, _ = listener.accept()
            threading.Thread(target=serve, args=(connection,), daemon=True).start()

    threading.Thread(target=accept, daemon=True).start()
    for _ in sys.stdin:  # lives until stdin closes
        pass


def connected_client(port):
    """pymodbus's TCP client (timeout 3 s) connected to 127.0.0.1:PORT, having said "ready"; None, having said why."""
    from pymodbus.client import ModbusTcpClient

    client = ModbusTcpClient("127.0.0.1", port=port, timeout=3, retries=0, retry_on_empty=False)
    if not client.connect():
        say("error cannot connect")
        return None
    say("ready")
    return client


def run_client(port, unit):
    client = connected_client(port)
    if client is None:
        return
    for line in sys.stdin:
        words = line.split()
        if not words:
            continue
        try:
            address = int(words[1])
            if words[0] == "read_coils":
                reply = client.read_coils(address, int(words[2]), slave=unit)
            elif words[0] == "read_inputs":
                reply = client.read_discrete_inputs(address, int(words[2]), slave=unit)
            elif words[0] == "read_holding":
                reply = client.read_holding_registers(address, int(words[2]), slave=unit)
            elif words[0] == "write_coil":
                reply = client.write_coil(address, words[2] == "1", slave=unit)
            elif words[0] == "write_coils":
                reply = client.write_coils(address, [v == "1" for v in words[2].split(",")], slave=unit)
            else:
                say("error unknown command " + words[0])
                continue
        except Exception as error:  # pylint: disable=broad-except
            say("error " + str(error).replace("\n", " "))
            continue
        if reply.isError():
            code = getattr(reply, "exception_code", None)
            say("exception %d" % code if code is not None else "error " + str(reply).replace("\n", " "))
        elif words[0] in ("read_coils", "read_inputs"):
            say(" ".join(["ok"] + ["1" if b else "0" for b in reply.bits[:int(words[2])]]))
        else:
            say("ok")
    client.close()


def run_plc(port, max_scans):
    client = connected_client(port)
    if client is None:
        return
    scan = [0]

    def log(reply):
        if not hasattr(reply, "function_code"):  # no valid answer
            say("error " + str(reply).replace("\n", " "))
            return None
        pdu = bytes([reply.function_code]) + reply.encode()
        say("%d %d %s" % (scan[0], reply.transaction_id, pdu.hex()))
        return reply

    log(client.write_coil(0, True, slave=1))
    eye = None
    while eye is None and scan[0] < max_scans:
        scan[0] += 1
        reply = log(client.read_discrete_inputs(0, 4, slave=1))
        if reply is None or reply.isError():
            break
        if reply.bits[0]:
            eye = scan[0]
    log(client.write_coil(0, False, slave=1))
    log(client.read_coils(0, 3, slave=1))
    say("eye at scan %d" % eye if eye is not None else "no eye in %d scans" % max_scans)
    say("end")
    client.close()


def main():
    mode = sys.argv[1] if len(sys.argv) > 1 else ""
    if mode == "server":
        run_pymodbus_server()
    elif mode == "junk":
        run_raw_server(True)
    elif mode == "silent":
        run_raw_server(False)
    elif mode == "late" and len(sys.argv) >= 3:
        run_raw_server(True, late=float(sys.argv[2]))
    elif mode == "client" and len(sys.argv) >= 3:
        run_client(int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 1)
    elif mode == "plc" and len(sys.argv) >= 4:
        run_plc(int(sys.argv[2]), int(sys.argv[3]))
    else:
        sys.stderr.write(__doc__)
        sys.exit(2)


if __name__ == "__main__":
    main()
