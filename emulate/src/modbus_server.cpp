#include "cellwright/emulate/modbus_server.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <modbus/modbus.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstring>
#include <utility>

namespace cellwright::emulate {

namespace {

using Clock = std::chrono::steady_clock;

constexpr std::size_t kHeader = 7;      // MBAP: transaction (2), protocol (2), length (2), unit (1)
constexpr int kMaxMbapLength = 254;     // unit + a PDU of at most 253 bytes
constexpr int kIllegalFunction = 1;
constexpr int kIllegalAddress = 2;
constexpr int kIllegalValue = 3;
constexpr int kDeviceFailure = 4;
constexpr int kGatewayPath = 10;
constexpr int kGatewayTarget = 11;

int word(const std::uint8_t* p) { return (p[0] << 8) | p[1]; }

}  // namespace

struct ModbusServer::Client {
  int fd = -1;
  int id = 0;
  std::vector<std::uint8_t> buffer;  // bytes received and not yet answered (at most one incomplete frame's worth)
};

ModbusServer::ModbusServer(drivers::DigitalIo& backend, ModbusServerOptions options, const SourceLocation& where)
    : backend_(backend), options_(std::move(options)) {
  const std::string at = fmt::format("{}:{}", options_.host, options_.port);
  if (options_.port < 0 || options_.port > 65535) {
    throw InputError(where, fmt::format("cannot listen on {}: the port must be within 1..65535 (0: any free one)", at));
  }
  if (options_.unit < 0 || options_.unit > 255) {
    throw InputError(where, fmt::format("the unit {} is not within 0..255", options_.unit));
  }
  if (options_.max_clients < 1) {
    throw InputError(where, fmt::format("max_clients must be at least 1, got {}", options_.max_clients));
  }
  addrinfo hints{};
  hints.ai_flags = AI_PASSIVE;
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  if (const int gai = getaddrinfo(options_.host.c_str(), nullptr, &hints, &found); gai != 0) {
    throw InputError(where, fmt::format("cannot listen on {}: '{}' does not resolve: {}", at, options_.host,
                                        gai_strerror(gai)));
  }
  freeaddrinfo(found);
  ctx_ = modbus_new_tcp_pi(options_.host.c_str(), std::to_string(options_.port).c_str());
  if (ctx_ == nullptr) throw InputError(where, fmt::format("cannot listen on {}: {}", at, modbus_strerror(errno)));
  listen_fd_ = modbus_tcp_pi_listen(ctx_, options_.max_clients);
  if (listen_fd_ < 0) {
    const int e = errno;
    modbus_free(ctx_);
    throw InputError(where, fmt::format("cannot listen on {}: {}", at, std::strerror(e)));
  }
  sockaddr_storage bound{};
  socklen_t len = sizeof bound;
  ::getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&bound), &len);
  port_ = bound.ss_family == AF_INET6 ? ntohs(reinterpret_cast<sockaddr_in6*>(&bound)->sin6_port)
                                      : ntohs(reinterpret_cast<sockaddr_in*>(&bound)->sin_port);
  ::fcntl(listen_fd_, F_SETFL, ::fcntl(listen_fd_, F_GETFL) | O_NONBLOCK);
  mapping_ = modbus_mapping_new(65536, 65536, 0, 0);
  const bool piped = ::pipe2(wake_, O_CLOEXEC | O_NONBLOCK) == 0;
  if (mapping_ == nullptr || !piped) {
    const int e = errno;
    ::close(listen_fd_);
    modbus_free(ctx_);
    if (mapping_ != nullptr) modbus_mapping_free(mapping_);
    throw InputError(where, fmt::format("cannot serve on {}: {}", at, std::strerror(e)));
  }
  backend_.connect();  // a failure is answered per request (exception 10), and retried then
}

ModbusServer::~ModbusServer() {
  stop();
  while (!clients_.empty()) close_client(clients_.size() - 1);
  modbus_set_socket(ctx_, -1);  // its socket was a client's, closed above
  modbus_free(ctx_);
  modbus_mapping_free(mapping_);
  ::close(listen_fd_);
  ::close(wake_[0]);
  ::close(wake_[1]);
}

ModbusServerOptions parse_listen_address(std::string_view host_port, const SourceLocation& where) {
  ModbusServerOptions out;
  const std::size_t colon = host_port.rfind(':');
  const std::string_view port = colon == std::string_view::npos ? std::string_view() : host_port.substr(colon + 1);
  const auto [end, ec] = std::from_chars(port.data(), port.data() + port.size(), out.port);
  if (colon == std::string_view::npos || colon == 0 || port.empty() || ec != std::errc() ||
      end != port.data() + port.size() || out.port < 0 || out.port > 65535) {
    throw InputError(where, fmt::format("'{}' is not HOST:PORT with a port within 0..65535 (0: a free one)",
                                        host_port));
  }
  out.host = std::string(host_port.substr(0, colon));
  return out;
}

std::string ModbusServer::endpoint() const { return fmt::format("{}:{}", options_.host, port_); }

void ModbusServer::set_hook(std::function<void(const ServedRequest&)> hook) { hook_ = std::move(hook); }

void ModbusServer::start() {
  CW_CHECK(!running_, "ModbusServer::start() while it already serves on its thread");
  stopping_ = false;
  running_ = true;
  thread_ = std::thread([this] {
    while (!stopping_) poll_and_serve(std::chrono::nanoseconds(-1));
  });
}

void ModbusServer::stop() {
  if (!running_) return;
  stopping_ = true;
  const char byte = 's';
  while (::write(wake_[1], &byte, 1) < 0 && errno == EINTR) {
  }
  thread_.join();
  running_ = false;
}

int ModbusServer::serve(std::chrono::nanoseconds wait) {
  CW_CHECK(!running_, "ModbusServer::serve() called while the server runs on its own thread");
  return poll_and_serve(wait);
}

int ModbusServer::poll_and_serve(std::chrono::nanoseconds wait) {
  std::vector<pollfd> fds;
  fds.reserve(clients_.size() + 2);
  fds.push_back({listen_fd_, POLLIN, 0});
  fds.push_back({wake_[0], POLLIN, 0});
  for (const auto& c : clients_) fds.push_back({c->fd, POLLIN, 0});
  timespec ts{};
  if (wait.count() > 0) {
    ts.tv_sec = static_cast<time_t>(wait.count() / 1000000000);
    ts.tv_nsec = static_cast<long>(wait.count() % 1000000000);
  }
  if (::ppoll(fds.data(), fds.size(), wait.count() < 0 ? nullptr : &ts, nullptr) <= 0) return 0;
  if (fds[1].revents != 0) {
    char drain[16];
    while (::read(wake_[0], drain, sizeof drain) > 0) {
    }
  }
  int served = 0;
  // Clients that have sent something (or hung up), from the last to the first so that closing one keeps the
  // indices of those before it.
  for (std::size_t i = clients_.size(); i-- > 0;) {
    if (fds[i + 2].revents != 0 && !read_client(*clients_[i], served)) close_client(i);
  }
  if (fds[0].revents != 0) {
    const std::size_t before = clients_.size();
    accept_clients();
    // A new client may have sent its first request along with the connection: serve it now.
    for (std::size_t i = clients_.size(); i-- > before;) {
      if (!read_client(*clients_[i], served)) close_client(i);
    }
  }
  return served;
}

void ModbusServer::accept_clients() {
  for (;;) {
    const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      return;  // EAGAIN: no more waiting; anything else: try again at the next poll
    }
    if (static_cast<int>(clients_.size()) >= options_.max_clients) {
      ::close(fd);
      continue;
    }
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    auto c = std::make_unique<Client>();
    c->fd = fd;
    c->id = next_client_++;
    clients_.push_back(std::move(c));
    ++open_clients_;
  }
}

void ModbusServer::close_client(std::size_t index) {
  ::close(clients_[index]->fd);
  clients_.erase(clients_.begin() + static_cast<std::ptrdiff_t>(index));
  --open_clients_;
}

bool ModbusServer::read_client(Client& c, int& served) {
  std::uint8_t chunk[1024];
  // A bounded number of reads per call, so that a client that sends without pause cannot keep the others waiting;
  // what is left is read at the next poll.
  for (int reads = 0; reads < 16; ++reads) {
    const ssize_t n = ::recv(c.fd, chunk, sizeof chunk, MSG_DONTWAIT);
    if (n == 0) return false;  // the client closed its end
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) return true;
      return false;  // reset, or another error: the connection is gone
    }
    c.buffer.insert(c.buffer.end(), chunk, chunk + n);
    // Answer every complete frame; keep an incomplete one for the next read.
    std::size_t at = 0;
    while (c.buffer.size() - at >= kHeader) {
      const std::uint8_t* f = c.buffer.data() + at;
      const int length = word(f + 4);
      if (word(f + 2) != 0 || length < 2 || length > kMaxMbapLength) return false;  // not Modbus TCP
      const std::size_t total = 6 + static_cast<std::size_t>(length);
      if (c.buffer.size() - at < total) break;
      if (!answer(c, f, total)) return false;
      ++served;
      at += total;
    }
    c.buffer.erase(c.buffer.begin(), c.buffer.begin() + static_cast<std::ptrdiff_t>(at));
  }
  return true;
}

int ModbusServer::backend_exception(const drivers::IoResult& r) {
  switch (r.status) {
    case drivers::IoStatus::ok: return 0;
    case drivers::IoStatus::exception:
      return r.exception_code >= 1 && r.exception_code < MODBUS_EXCEPTION_MAX ? r.exception_code : kDeviceFailure;
    case drivers::IoStatus::timeout: return kGatewayTarget;
    case drivers::IoStatus::disconnected: return kGatewayPath;
    case drivers::IoStatus::protocol: return kDeviceFailure;
  }
  return kDeviceFailure;
}

bool ModbusServer::answer(Client& c, const std::uint8_t* frame, std::size_t length) {
  const Clock::time_point t0 = Clock::now();
  const std::uint8_t* pdu = frame + kHeader;
  const std::size_t pdu_length = length - kHeader;
  ServedRequest s;
  s.client = c.id;
  s.unit = frame[6];
  s.function = pdu[0];
  const bool reads = s.function == MODBUS_FC_READ_COILS || s.function == MODBUS_FC_READ_DISCRETE_INPUTS;
  const bool known = reads || s.function == MODBUS_FC_WRITE_SINGLE_COIL || s.function == MODBUS_FC_WRITE_MULTIPLE_COILS;
  // Function 5's second word is the value; the others' the count.
  const int count = pdu_length >= 5 ? word(pdu + 3) : 0;
  if (known && pdu_length >= 5) {
    s.address = static_cast<std::uint16_t>(word(pdu + 1));
    s.count = static_cast<std::uint16_t>(s.function == MODBUS_FC_WRITE_SINGLE_COIL ? 1 : count);
  }
  int code = 0;
  if (s.unit != options_.unit) {
    code = kGatewayTarget;
  } else if (!known) {
    code = kIllegalFunction;
  } else if (reads) {
    if (pdu_length != 5 || count < 1 || count > MODBUS_MAX_READ_BITS) {
      code = kIllegalValue;
    } else if (s.address + count > 65536) {
      code = kIllegalAddress;
    }
  } else if (s.function == MODBUS_FC_WRITE_SINGLE_COIL) {
    if (pdu_length != 5 || (count != 0xFF00 && count != 0x0000)) code = kIllegalValue;
  } else if (pdu_length < 6 || count < 1 || count > MODBUS_MAX_WRITE_BITS || pdu[5] != (count + 7) / 8 ||
             pdu_length != 6 + static_cast<std::size_t>(pdu[5])) {
    code = kIllegalValue;
  } else if (s.address + count > 65536) {
    code = kIllegalAddress;
  }
  if (code == 0 && !backend_.is_open()) code = backend_exception(backend_.connect());
  if (code == 0) {
    if (reads) {
      const bool inputs = s.function == MODBUS_FC_READ_DISCRETE_INPUTS;
      const drivers::IoResult r = inputs ? backend_.read_inputs(s.address, s.count, values_)
                                         : backend_.read_coils(s.address, s.count, values_);
      code = backend_exception(r);
      if (code == 0 && values_.size() != s.count) code = kDeviceFailure;
      if (code == 0) {
        std::uint8_t* image = inputs ? mapping_->tab_input_bits : mapping_->tab_bits;
        for (std::size_t i = 0; i < values_.size(); ++i) image[s.address + i] = values_[i] ? 1 : 0;
      }
    } else if (s.function == MODBUS_FC_WRITE_SINGLE_COIL) {
      code = backend_exception(backend_.write_coil(s.address, count == 0xFF00));
    } else {
      for (int i = 0; i < count && code == 0; ++i) {
        const bool on = ((pdu[6 + i / 8] >> (i % 8)) & 1) != 0;
        code = backend_exception(backend_.write_coil(static_cast<std::uint16_t>(s.address + i), on));
      }
    }
  }
  ++requests_;  // before the answer goes, so that a client holding its answer sees its request counted
  modbus_set_socket(ctx_, c.fd);
  const int sent = code != 0 ? modbus_reply_exception(ctx_, frame, static_cast<unsigned>(code))
                             : modbus_reply(ctx_, frame, static_cast<int>(length), mapping_);
  if (sent < 0) return false;
  s.exception_code = code;
  s.processing = Clock::now() - t0;
  if (hook_) hook_(s);
  return true;
}

}  // namespace cellwright::emulate
