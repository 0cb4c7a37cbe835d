#include "model/distributed/rendezvous_store.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/types.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <thread>

#include "util/error.h"
#include "util/hex.h"

namespace nbtf::detail {

// Wire format: every message is a frame, a 4-byte little-endian length and that many bytes.
// The first frame of a connection is the handshake, kMagic + the secret; the server answers
// "OK" or closes the connection. Then each request frame (an op byte, then fields: 4-byte
// length + bytes, or 8-byte integers) gets one reply frame.
namespace {

constexpr char kMagic[] = "NBTFRDV1";
constexpr std::size_t kMagicSize = sizeof kMagic - 1;
constexpr std::uint32_t kMaxHandshake = 4096;          // a stranger cannot make the server buffer more
constexpr std::uint32_t kMaxFrame = 256u << 20;        // Gloo's keys hold addresses: small
constexpr auto kHandshakeWindow = std::chrono::seconds(10);  // to present the secret after connecting

void putU32(StoreBytes& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void putI64(StoreBytes& out, std::int64_t value) {
  const auto v = static_cast<std::uint64_t>(value);
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void putField(StoreBytes& out, const void* data, std::size_t n) {
  putU32(out, static_cast<std::uint32_t>(n));
  const auto* p = static_cast<const std::uint8_t*>(data);
  out.insert(out.end(), p, p + n);
}
void putField(StoreBytes& out, const std::string& s) { putField(out, s.data(), s.size()); }
void putField(StoreBytes& out, const StoreBytes& b) { putField(out, b.data(), b.size()); }
std::uint32_t readU32(const std::uint8_t* p) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(p[i]) << (8 * i);
  return v;
}

// Reads the fields of one frame; throws std::runtime_error when it is malformed.
struct Reader {
  const StoreBytes& b;
  std::size_t at = 0;
  std::uint8_t byte() {
    if (at >= b.size()) throw std::runtime_error("truncated message");
    return b[at++];
  }
  StoreBytes field() {
    if (b.size() - at < 4) throw std::runtime_error("truncated message");
    const std::uint32_t n = readU32(&b[at]);
    at += 4;
    if (b.size() - at < n) throw std::runtime_error("truncated message");
    StoreBytes out(b.begin() + static_cast<std::ptrdiff_t>(at), b.begin() + static_cast<std::ptrdiff_t>(at + n));
    at += n;
    return out;
  }
  std::string text() {
    const StoreBytes f = field();
    return std::string(f.begin(), f.end());
  }
  std::int64_t i64() {
    if (b.size() - at < 8) throw std::runtime_error("truncated message");
    std::uint64_t v = 0;
    for (int i = 0; i < 8; ++i) v |= static_cast<std::uint64_t>(b[at + i]) << (8 * i);
    at += 8;
    return static_cast<std::int64_t>(v);
  }
  std::uint32_t u32() {
    if (b.size() - at < 4) throw std::runtime_error("truncated message");
    const std::uint32_t v = readU32(&b[at]);
    at += 4;
    return v;
  }
};

std::string addressText(const sockaddr* a) {
  char host[INET6_ADDRSTRLEN] = "?";
  int port = 0;
  if (a->sa_family == AF_INET) {
    const auto* in = reinterpret_cast<const sockaddr_in*>(a);
    inet_ntop(AF_INET, &in->sin_addr, host, sizeof host);
    port = ntohs(in->sin_port);
    return std::string(host) + ":" + std::to_string(port);
  }
  if (a->sa_family == AF_INET6) {
    const auto* in = reinterpret_cast<const sockaddr_in6*>(a);
    inet_ntop(AF_INET6, &in->sin6_addr, host, sizeof host);
    port = ntohs(in->sin6_port);
    return "[" + std::string(host) + "]:" + std::to_string(port);
  }
  return "?";
}

struct AddrInfo {
  addrinfo* list = nullptr;
  AddrInfo(const std::string& host, int port, bool passive) {
    addrinfo hints{};
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_NUMERICSERV | (passive ? 0 : AI_ADDRCONFIG);
    const int rc = getaddrinfo(host.c_str(), std::to_string(port).c_str(), &hints, &list);
    if (rc != 0 || !list)
      throw Error("--master: cannot resolve host '" + host + "': " + gai_strerror(rc));
  }
  ~AddrInfo() {
    if (list) freeaddrinfo(list);
  }
};

// Sends all of `data` on a (possibly non-blocking) socket, waiting at most `limit` in all.
bool sendAll(int fd, const std::uint8_t* data, std::size_t n, std::chrono::milliseconds limit) {
  const auto deadline = StoreClock::now() + limit;
  while (n > 0) {
    const ssize_t sent = ::send(fd, data, n, MSG_NOSIGNAL);
    if (sent > 0) {
      data += sent, n -= static_cast<std::size_t>(sent);
      continue;
    }
    if (sent < 0 && errno == EINTR) continue;
    if (sent < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - StoreClock::now()).count();
      if (left <= 0) return false;
      pollfd p{fd, POLLOUT, 0};
      ::poll(&p, 1, static_cast<int>(left));
      continue;
    }
    return false;
  }
  return true;
}

bool sendFrame(int fd, const StoreBytes& body, std::chrono::milliseconds limit) {
  StoreBytes frame;
  frame.reserve(body.size() + 4);
  putU32(frame, static_cast<std::uint32_t>(body.size()));
  frame.insert(frame.end(), body.begin(), body.end());
  return sendAll(fd, frame.data(), frame.size(), limit);
}

// Blocking receive of exactly n bytes (the socket's SO_RCVTIMEO bounds each wait).
bool recvAll(int fd, std::uint8_t* data, std::size_t n) {
  while (n > 0) {
    const ssize_t got = ::recv(fd, data, n, 0);
    if (got > 0) {
      data += got, n -= static_cast<std::size_t>(got);
      continue;
    }
    if (got < 0 && errno == EINTR) continue;
    return false;
  }
  return true;
}

void setTimeouts(int fd, std::chrono::milliseconds t) {
  timeval tv{};
  tv.tv_sec = static_cast<time_t>(t.count() / 1000);
  tv.tv_usec = static_cast<suseconds_t>((t.count() % 1000) * 1000);
  if (tv.tv_sec == 0 && tv.tv_usec == 0) tv.tv_usec = 1000;  // 0 would mean "no timeout"
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
}

std::string keyList(const std::vector<std::string>& keys) {
  std::string s;
  for (const std::string& k : keys) s += (s.empty() ? "" : ", ") + k;
  return s;
}

}  // namespace

bool sameSecret(const std::string& given, const std::string& secret) {
  if (secret.empty()) return false;
  unsigned diff = given.size() != secret.size() ? 1u : 0u;
  for (std::size_t i = 0; i < given.size(); ++i)
    diff |= static_cast<unsigned char>(given[i]) ^ static_cast<unsigned char>(secret[i % secret.size()]);
  return diff == 0;
}

std::string randomSecret() {
  std::ifstream in("/dev/urandom", std::ios::binary);
  unsigned char bytes[16];
  if (!in.read(reinterpret_cast<char*>(bytes), sizeof bytes))
    throw Error("cannot read /dev/urandom to generate a --dist-secret; pass one with --dist-secret");
  return toHex(bytes, sizeof bytes);
}

// ---------------------------------------------------------------------------------------------
// Server: one thread, poll() over the listening socket and the connections (non-blocking), so a
// silent or slow peer cannot stall the others.

struct RendezvousServer::Impl {
  struct Conn {
    int fd = -1;
    std::string peer;
    bool authenticated = false;
    StoreClock::time_point accepted;
    StoreBytes in;
  };
  int listenFd = -1;
  int wake[2] = {-1, -1};
  std::string secret, address;
  std::map<std::string, StoreBytes> values;
  std::vector<Conn> conns;
  std::thread thread;

  void refuse(Conn& c, const std::string& why) {
    std::fprintf(stderr, "nbtf: rendezvous at %s: refused the connection from %s: %s\n", address.c_str(),
                 c.peer.c_str(), why.c_str());
    ::close(c.fd);
    c.fd = -1;
  }

  // One request of an authenticated peer -> its reply.
  StoreBytes handle(const StoreBytes& body) {
    Reader r{body};
    const char op = static_cast<char>(r.byte());
    StoreBytes out;
    switch (op) {
      case 'S': {
        std::string key = r.text();
        values[key] = r.field();
        out.push_back('K');
        break;
      }
      case 'G': {
        auto it = values.find(r.text());
        if (it == values.end()) {
          out.push_back('N');
        } else {
          out.push_back('Y');
          putField(out, it->second);
        }
        break;
      }
      case 'A': {
        const std::string key = r.text();
        const std::int64_t delta = r.i64();
        std::int64_t v = 0;
        auto it = values.find(key);
        if (it != values.end()) {
          try {
            v = std::stoll(std::string(it->second.begin(), it->second.end()));
          } catch (const std::exception&) {
            throw std::runtime_error("add on a key that holds no integer: " + key);
          }
        }
        v += delta;
        const std::string text = std::to_string(v);
        values[key] = StoreBytes(text.begin(), text.end());
        out.push_back('K');
        putI64(out, v);
        break;
      }
      case 'C': {
        const std::string key = r.text();
        StoreBytes expected = r.field(), desired = r.field();
        auto it = values.find(key);
        StoreBytes result;
        if (it == values.end()) {
          if (expected.empty()) values[key] = desired, result = desired;
          else result = expected;
        } else if (it->second == expected) {
          it->second = desired, result = desired;
        } else {
          result = it->second;
        }
        out.push_back('K');
        putField(out, result);
        break;
      }
      case 'H': {
        const std::uint32_t n = r.u32();
        bool all = true;
        for (std::uint32_t i = 0; i < n; ++i) all = values.count(r.text()) > 0 && all;
        out.push_back(all ? 'Y' : 'N');
        break;
      }
      case 'D':
        out.push_back(values.erase(r.text()) ? 'Y' : 'N');
        break;
      case 'n':
        out.push_back('K');
        putI64(out, static_cast<std::int64_t>(values.size()));
        break;
      default:
        throw std::runtime_error("unknown request");
    }
    return out;
  }

  // Handles the complete frames in c.in; closes the connection (c.fd = -1) on a refusal.
  void process(Conn& c) {
    while (c.fd >= 0 && c.in.size() >= 4) {
      const std::uint32_t n = readU32(c.in.data());
      if (!c.authenticated && n > kMaxHandshake) return refuse(c, "no shared secret (not an nbtf rank?)");
      if (n > kMaxFrame) return refuse(c, "a message of " + std::to_string(n) + " bytes");
      if (c.in.size() < 4 + static_cast<std::size_t>(n)) return;
      const StoreBytes body(c.in.begin() + 4, c.in.begin() + 4 + n);
      c.in.erase(c.in.begin(), c.in.begin() + 4 + n);
      if (!c.authenticated) {
        const bool magic = body.size() >= kMagicSize && std::memcmp(body.data(), kMagic, kMagicSize) == 0;
        const std::string given(body.begin() + static_cast<std::ptrdiff_t>(magic ? kMagicSize : 0), body.end());
        if (!magic) return refuse(c, "no shared secret (not an nbtf rank?)");
        if (!sameSecret(given, secret))
          return refuse(c, "wrong shared secret (--dist-secret / NBTF_DIST_SECRET differs from rank 0's)");
        c.authenticated = true;
        if (!sendFrame(c.fd, StoreBytes{'O', 'K'}, std::chrono::seconds(10))) ::close(c.fd), c.fd = -1;
        continue;
      }
      StoreBytes reply;
      try {
        reply = handle(body);
      } catch (const std::exception& e) {
        return refuse(c, std::string("malformed request (") + e.what() + ")");
      }
      if (!sendFrame(c.fd, reply, std::chrono::seconds(30))) ::close(c.fd), c.fd = -1;
    }
  }

  void run() {
    for (;;) {
      std::vector<pollfd> fds{{wake[0], POLLIN, 0}, {listenFd, POLLIN, 0}};
      for (const Conn& c : conns) fds.push_back({c.fd, POLLIN, 0});
      const int rc = ::poll(fds.data(), fds.size(), 250);
      if (rc < 0 && errno != EINTR) return;
      if (fds[0].revents) return;  // the destructor asks to stop
      if (fds[1].revents & POLLIN) {
        sockaddr_storage peer{};
        socklen_t len = sizeof peer;
        const int fd = ::accept4(listenFd, reinterpret_cast<sockaddr*>(&peer), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
        if (fd >= 0) {
          Conn c;
          c.fd = fd;
          c.peer = addressText(reinterpret_cast<sockaddr*>(&peer));
          c.accepted = StoreClock::now();
          conns.push_back(std::move(c));
        }
      }
      for (std::size_t i = 0; i < conns.size(); ++i) {
        Conn& c = conns[i];
        const short ev = i + 2 < fds.size() ? fds[i + 2].revents : 0;
        if (ev & (POLLIN | POLLHUP | POLLERR)) {
          std::uint8_t buf[65536];
          const ssize_t got = ::recv(c.fd, buf, sizeof buf, 0);
          if (got > 0) {
            c.in.insert(c.in.end(), buf, buf + got);
            process(c);
          } else if (got == 0 || (errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR)) {
            ::close(c.fd);
            c.fd = -1;
          }
        }
        if (c.fd >= 0 && !c.authenticated && StoreClock::now() - c.accepted > kHandshakeWindow)
          refuse(c, "no shared secret within 10 s");
      }
      conns.erase(std::remove_if(conns.begin(), conns.end(), [](const Conn& c) { return c.fd < 0; }), conns.end());
    }
  }

  ~Impl() {
    for (Conn& c : conns)
      if (c.fd >= 0) ::close(c.fd);
    if (listenFd >= 0) ::close(listenFd);
    for (int fd : wake)
      if (fd >= 0) ::close(fd);
  }
};

RendezvousServer::RendezvousServer(const std::string& host, int port, const std::string& secret) : impl_(new Impl) {
  if (secret.empty()) throw Error("the rendezvous needs a shared secret (--dist-secret or NBTF_DIST_SECRET)");
  impl_->secret = secret;
  AddrInfo ai(host, port, true);
  int lastErrno = 0;
  std::string lastAddress;
  for (addrinfo* a = ai.list; a; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) {
      lastErrno = errno;
      continue;
    }
    // SO_REUSEADDR lets a new run take the port of a finished one (TIME_WAIT); Linux still
    // refuses it while anything listens there.
    const int one = 1;
    setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    if (a->ai_family == AF_INET6) setsockopt(fd, IPPROTO_IPV6, IPV6_V6ONLY, &one, sizeof one);
    lastAddress = addressText(a->ai_addr);
    if (::bind(fd, a->ai_addr, a->ai_addrlen) == 0 && ::listen(fd, 128) == 0) {
      impl_->listenFd = fd;
      impl_->address = lastAddress;
      break;
    }
    lastErrno = errno;
    ::close(fd);
  }
  if (impl_->listenFd < 0) {
    const std::string where = "port " + std::to_string(port) + " on " + host;
    if (lastErrno == EADDRINUSE)
      throw Error(where + " is already in use (another run or service listens there): pick another --master port");
    if (lastErrno == EADDRNOTAVAIL)
      throw Error("--master " + host + ":" + std::to_string(port) + ": " + host + " (" + lastAddress +
                  ") is not an address of this machine; rank 0 runs on the --master host");
    if (lastErrno == EACCES) throw Error(where + ": permission denied (ports below 1024 need privileges)");
    throw Error("cannot listen on " + where + ": " + std::strerror(lastErrno));
  }
  fcntl(impl_->listenFd, F_SETFL, fcntl(impl_->listenFd, F_GETFL) | O_NONBLOCK);
  if (::pipe2(impl_->wake, O_CLOEXEC) != 0) throw Error(std::string("rendezvous: pipe: ") + std::strerror(errno));
  impl_->thread = std::thread([impl = impl_.get()] { impl->run(); });
}

RendezvousServer::~RendezvousServer() {
  if (impl_->thread.joinable()) {
    const char stop = 1;
    if (::write(impl_->wake[1], &stop, 1) < 0) {
    }  // the thread also ends on the closed pipe below
    impl_->thread.join();
  }
}

const std::string& RendezvousServer::address() const { return impl_->address; }

// ---------------------------------------------------------------------------------------------
// Client: one blocking connection, one request at a time.

RendezvousClient::RendezvousClient(const std::string& host, int port, const std::string& secret,
                                   StoreClock::time_point deadline)
    : where_("rank 0's rendezvous at " + host + ":" + std::to_string(port)) {
  if (secret.empty()) throw Error("the rendezvous needs a shared secret (--dist-secret or NBTF_DIST_SECRET)");
  std::string lastError = "no address";
  for (;;) {
    {
      AddrInfo ai(host, port, false);
      for (addrinfo* a = ai.list; a && fd_ < 0; a = a->ai_next) {
        const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
        if (fd < 0) continue;
        const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - StoreClock::now());
        setTimeouts(fd, std::clamp(left, std::chrono::milliseconds(1), std::chrono::milliseconds(5000)));
        if (::connect(fd, a->ai_addr, a->ai_addrlen) == 0) {
          fd_ = fd;
        } else {
          lastError = std::strerror(errno);
          ::close(fd);
        }
      }
    }
    if (fd_ >= 0) break;
    if (StoreClock::now() >= deadline)
      throw Error("could not reach " + where_ + " (" + lastError + "): is rank 0 running with this --master?");
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  const int one = 1;
  setsockopt(fd_, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  // Rank 0's server answers every request at once; a minute without an answer is a dead peer.
  setTimeouts(fd_, std::chrono::seconds(60));
  StoreBytes hello(kMagic, kMagic + kMagicSize);
  hello.insert(hello.end(), secret.begin(), secret.end());
  std::uint8_t head[4];
  StoreBytes reply(2);
  if (!sendFrame(fd_, hello, std::chrono::seconds(60)) || !recvAll(fd_, head, 4) || readU32(head) != 2 ||
      !recvAll(fd_, reply.data(), 2) || reply != StoreBytes{'O', 'K'}) {
    ::close(fd_);
    fd_ = -1;
    throw Error(where_ + " refused this rank: its shared secret (--dist-secret / NBTF_DIST_SECRET) is not rank 0's "
                "(or something other than an nbtf rank 0 listens there)");
  }
}

RendezvousClient::~RendezvousClient() {
  if (fd_ >= 0) ::close(fd_);
}

StoreBytes RendezvousClient::request(const StoreBytes& body) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::uint8_t head[4];
  if (fd_ < 0 || !sendFrame(fd_, body, std::chrono::seconds(60)) || !recvAll(fd_, head, 4))
    throw Error(where_ + ": connection lost (rank 0 stopped or closed it)");
  const std::uint32_t n = readU32(head);
  if (n > kMaxFrame) throw Error(where_ + ": malformed reply");
  StoreBytes reply(n);
  if (!recvAll(fd_, reply.data(), n) || reply.empty())
    throw Error(where_ + ": connection lost (rank 0 stopped or closed it)");
  return reply;
}

void RendezvousClient::set(const std::string& key, const StoreBytes& value) {
  StoreBytes b{'S'};
  putField(b, key);
  putField(b, value);
  request(b);
}

std::optional<StoreBytes> RendezvousClient::tryGet(const std::string& key) {
  StoreBytes b{'G'};
  putField(b, key);
  const StoreBytes reply = request(b);
  if (reply[0] != 'Y') return std::nullopt;
  Reader r{reply, 1};
  return r.field();
}

StoreBytes RendezvousClient::get(const std::string& key, StoreClock::time_point deadline) {
  wait({key}, deadline);
  if (auto v = tryGet(key)) return *v;
  throw Error(where_ + ": key '" + key + "' was deleted while waited for");
}

std::int64_t RendezvousClient::add(const std::string& key, std::int64_t delta) {
  StoreBytes b{'A'};
  putField(b, key);
  putI64(b, delta);
  const StoreBytes reply = request(b);
  Reader r{reply, 1};
  return r.i64();
}

StoreBytes RendezvousClient::compareSet(const std::string& key, const StoreBytes& expected, const StoreBytes& desired) {
  StoreBytes b{'C'};
  putField(b, key);
  putField(b, expected);
  putField(b, desired);
  const StoreBytes reply = request(b);
  Reader r{reply, 1};
  return r.field();
}

bool RendezvousClient::check(const std::vector<std::string>& keys) {
  StoreBytes b{'H'};
  putU32(b, static_cast<std::uint32_t>(keys.size()));
  for (const std::string& k : keys) putField(b, k);
  return request(b)[0] == 'Y';
}

bool RendezvousClient::deleteKey(const std::string& key) {
  StoreBytes b{'D'};
  putField(b, key);
  return request(b)[0] == 'Y';
}

std::int64_t RendezvousClient::numKeys() {
  const StoreBytes reply = request(StoreBytes{'n'});
  Reader r{reply, 1};
  return r.i64();
}

void RendezvousClient::wait(const std::vector<std::string>& keys, StoreClock::time_point deadline) {
  // Polling is enough: a rendezvous waits seconds, not microseconds.
  auto pause = std::chrono::milliseconds(2);
  while (!check(keys)) {
    if (StoreClock::now() >= deadline)
      throw Error(where_ + ": timed out waiting for " + keyList(keys) + " (a rank did not get there)");
    std::this_thread::sleep_for(std::min<StoreClock::duration>(pause, deadline - StoreClock::now()));
    pause = std::min(pause * 2, std::chrono::milliseconds(50));
  }
}

}  // namespace nbtf::detail
