#include "cellwright/drivers/modbus/modbus_io.hpp"

#include <fmt/format.h>
#include <modbus/modbus.h>
#include <netdb.h>
#include <sys/socket.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <utility>

namespace cellwright::drivers {

namespace {

const char* exception_name(int code) {
  switch (code) {
    case 1: return "illegal function";
    case 2: return "illegal data address";
    case 3: return "illegal data value";
    case 4: return "server device failure";
    case 5: return "acknowledge";
    case 6: return "server device busy";
    case 7: return "negative acknowledge";
    case 8: return "memory parity error";
    case 10: return "gateway path unavailable";
    case 11: return "gateway target device failed to respond";
    default: return "not defined by Modbus";
  }
}

// A decimal number within lo..hi, nothing else; nullopt-like -1 otherwise.
int parse_bounded(std::string_view digits, int lo, int hi) {
  if (digits.empty() || digits.size() > 6) return -1;
  int value = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
  if (ec != std::errc() || end != digits.data() + digits.size() || value < lo || value > hi) return -1;
  return value;
}

// Why `host` is neither a dotted IPv4 address nor a host name (RFC 1123 labels); empty if it is one.
std::string host_problem(std::string_view host) {
  if (host.empty()) return "the host is empty";
  if (host.size() > 253) return "the host name is longer than 253 characters";
  const bool numeric = host.find_first_not_of("0123456789.") == std::string_view::npos;
  std::size_t parts = 0;
  std::size_t start = 0;
  while (start <= host.size()) {
    const std::size_t dot = std::min(host.find('.', start), host.size());
    const std::string_view label = host.substr(start, dot - start);
    ++parts;
    if (numeric) {
      if (parse_bounded(label, 0, 255) < 0 || label.size() > 3) {
        return fmt::format("'{}' is not an IPv4 address (four numbers 0..255 joined by dots)", host);
      }
    } else {
      if (label.empty() || label.size() > 63) {
        return fmt::format("'{}' is not a host name (a part between dots is empty or longer than 63)", host);
      }
      for (const char c : label) {
        const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-';
        if (!ok) return fmt::format("'{}' is not a host name ('{}' is not a letter, digit, '-' or '.')", host, c);
      }
      if (label.front() == '-' || label.back() == '-') {
        return fmt::format("'{}' is not a host name (a part starts or ends with '-')", host);
      }
    }
    start = dot + 1;
  }
  if (numeric && parts != 4) {
    return fmt::format("'{}' is not an IPv4 address (four numbers 0..255 joined by dots)", host);
  }
  return {};
}

}  // namespace

std::string ModbusAddress::str() const { return fmt::format("{}:{} unit {}", host, port, unit); }

ModbusAddress parse_modbus_address(std::string_view text, const SourceLocation& where) {
  const auto fail = [&](const std::string& problem) -> InputError {
    return InputError(where, fmt::format("'{}': {} (write modbus:HOST:PORT or modbus:HOST:PORT/UNIT, e.g. "
                                         "modbus:192.168.0.10:502/1)",
                                         text, problem));
  };
  constexpr std::string_view scheme = "modbus:";
  if (text.substr(0, scheme.size()) != scheme) throw fail("it does not start with 'modbus:'");
  std::string_view rest = text.substr(scheme.size());
  ModbusAddress a;
  if (const std::size_t slash = rest.find('/'); slash != std::string_view::npos) {
    const std::string_view unit = rest.substr(slash + 1);
    a.unit = parse_bounded(unit, 0, 247);
    if (a.unit < 0) throw fail(fmt::format("the unit '{}' is not a number within 0..247", unit));
    rest = rest.substr(0, slash);
  }
  const std::size_t colon = rest.rfind(':');
  if (colon == std::string_view::npos) throw fail("the port is missing");
  const std::string_view host = rest.substr(0, colon);
  const std::string_view port = rest.substr(colon + 1);
  if (host.find(':') != std::string_view::npos || host.find('[') != std::string_view::npos) {
    throw fail("IPv6 addresses are not taken; give a host name that resolves to one");
  }
  if (const std::string problem = host_problem(host); !problem.empty()) throw fail(problem);
  a.host = std::string(host);
  a.port = parse_bounded(port, 1, 65535);
  if (a.port < 0) throw fail(fmt::format("the port '{}' is not a number within 1..65535", port));
  return a;
}

ModbusIo::ModbusIo(ModbusAddress address, ModbusIoOptions options, const SourceLocation& where)
    : address_(std::move(address)), options_(options) {
  const double t = options_.response_timeout;
  if (!std::isfinite(t) || t <= 0 || t > 3600) {
    throw InputError(where, fmt::format("{}: the response timeout must be within 0..3600 s (above 0), got {}",
                                        describe(), t));
  }
  ctx_ = modbus_new_tcp_pi(address_.host.c_str(), std::to_string(address_.port).c_str());
  if (ctx_ == nullptr) {
    throw InputError(where, fmt::format("{}: libmodbus refused the address: {}", describe(), modbus_strerror(errno)));
  }
  const auto micros = static_cast<long long>(std::llround(t * 1e6));
  const bool set = modbus_set_slave(ctx_, address_.unit) == 0 &&
                   modbus_set_response_timeout(ctx_, static_cast<std::uint32_t>(micros / 1000000),
                                               static_cast<std::uint32_t>(micros % 1000000)) == 0 &&
                   modbus_set_byte_timeout(ctx_, 0, 0) == 0;  // no byte timeout: the response timeout bounds it all
  if (!set) {
    const int e = errno;
    modbus_free(ctx_);
    throw InputError(where, fmt::format("{}: libmodbus refused the settings: {}", describe(), modbus_strerror(e)));
  }
}

ModbusIo::~ModbusIo() {
  modbus_close(ctx_);
  modbus_free(ctx_);
}

std::string ModbusIo::describe() const { return "modbus " + address_.str(); }

IoResult ModbusIo::connect() {
  if (open_) return {};
  // Resolve first, for a message that says so (libmodbus reports a name that does not resolve as "refused").
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const int gai = getaddrinfo(address_.host.c_str(), nullptr, &hints, &found);
  if (gai != 0) {
    return {IoStatus::disconnected, 0,
            fmt::format("{}: connect: cannot resolve '{}': {}", describe(), address_.host, gai_strerror(gai))};
  }
  freeaddrinfo(found);
  errno = 0;
  if (modbus_connect(ctx_) != 0) {
    const int e = errno;
    modbus_close(ctx_);
    // libmodbus leaves EINPROGRESS (or nothing) when the connect was not answered within its timeout.
    const std::string why = e == EINPROGRESS || e == 0 || e == ETIMEDOUT
                                ? fmt::format("no answer within {} s", options_.response_timeout)
                                : std::string(modbus_strerror(e));
    return {IoStatus::disconnected, 0, fmt::format("{}: connect: {}", describe(), why)};
  }
  open_ = true;
  stale_ = false;
  return {};
}

void ModbusIo::close() {
  modbus_close(ctx_);
  open_ = false;
  stale_ = false;
}

bool ModbusIo::is_open() const { return open_; }

template <typename Send>
IoResult ModbusIo::request(const std::string& what, Send&& send) {
  if (!open_) return {IoStatus::disconnected, 0, fmt::format("{}: {}: the unit is not connected", describe(), what)};
  if (stale_) {
    modbus_flush(ctx_);
    stale_ = false;
  }
  errno = 0;
  if (send()) return {};
  const int e = errno;
  if (e > MODBUS_ENOBASE && e <= EMBXGTAR) {
    const int code = e - MODBUS_ENOBASE;
    return {IoStatus::exception, code,
            fmt::format("{}: {}: exception {} ({})", describe(), what, code, exception_name(code))};
  }
  if (e == ETIMEDOUT) {
    stale_ = true;
    return {IoStatus::timeout, 0,
            fmt::format("{}: {}: no answer within {} s", describe(), what, options_.response_timeout)};
  }
  const bool garbled = e == EMBBADDATA || e == EMBBADCRC || e == EMBBADEXC || e == EMBUNKEXC || e == EMBMDATA ||
                       e == EMBBADSLAVE || e == MODBUS_ENOBASE;
  close();
  if (garbled) {
    return {IoStatus::protocol, 0,
            fmt::format("{}: {}: not a valid answer ({}); the connection is closed", describe(), what,
                        modbus_strerror(e))};
  }
  const std::string why = e == ECONNRESET ? "the unit closed the connection" : std::string(modbus_strerror(e));
  return {IoStatus::disconnected, 0, fmt::format("{}: {}: {}; the connection is closed", describe(), what, why)};
}

IoResult ModbusIo::write_coil(std::uint16_t address, bool value) {
  return request(fmt::format("write coil {} {}", address, value ? "on" : "off"),
                 [&] { return modbus_write_bit(ctx_, address, value ? 1 : 0) == 1; });
}

IoResult ModbusIo::read_bits(bool inputs, std::uint16_t first, std::uint16_t count, std::vector<bool>& values) {
  CW_CHECK(count >= 1 && count <= MODBUS_MAX_READ_BITS && std::size_t{first} + count <= 65536,
           "{}: a read of {} values from {} (1..{} values within 0..65535)", describe(), count, first,
           MODBUS_MAX_READ_BITS);
  bits_.assign(count, 0);
  int got = -1;
  const IoResult r = request(
      fmt::format("read {} {}..{}", inputs ? "discrete inputs" : "coils", first, first + count - 1), [&] {
        got = inputs ? modbus_read_input_bits(ctx_, first, count, bits_.data())
                     : modbus_read_bits(ctx_, first, count, bits_.data());
        if (got < 0) return false;
        if (got != count) errno = EMBBADDATA;  // libmodbus checks the count; this keeps the promise if it did not
        return got == count;
      });
  if (r.ok()) {
    values.resize(count);
    for (std::size_t i = 0; i < count; ++i) values[i] = bits_[i] != 0;
  }
  return r;
}

IoResult ModbusIo::read_coils(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) {
  return read_bits(false, first, count, values);
}

IoResult ModbusIo::read_inputs(std::uint16_t first, std::uint16_t count, std::vector<bool>& values) {
  return read_bits(true, first, count, values);
}

}  // namespace cellwright::drivers
