// The rendezvous store of distributed training (model/distributed/rendezvous_store.h): its operations, its address, its shared secret.
#include "model/distributed/rendezvous_store.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <ifaddrs.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "socket_fixtures.h"
#include "test_util.h"

namespace nbtf {
namespace {

using test::freePort;
using test::listenOn;

// The local addresses (as /proc/net/tcp writes them, hex) of the sockets listening on `port`.
std::vector<std::string> listeningAddresses(int port) {
  std::vector<std::string> found;
  char portHex[8];
  std::snprintf(portHex, sizeof portHex, ":%04X", port);
  for (const char* table : {"/proc/net/tcp", "/proc/net/tcp6"}) {
    std::ifstream in(table);
    std::string line;
    std::getline(in, line);  // header
    while (std::getline(in, line)) {
      std::istringstream fields(line);
      std::string slot, local, remote, state;
      fields >> slot >> local >> remote >> state;
      if (state == "0A" && local.size() > 5 && local.substr(local.size() - 5) == portHex)
        found.push_back(local.substr(0, local.size() - 5));
    }
  }
  return found;
}

// An IPv4 address of this machine that is not loopback ("" when it has none).
std::string nonLoopbackAddress() {
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return "";
  std::string found;
  for (ifaddrs* i = list; i && found.empty(); i = i->ifa_next) {
    if (!i->ifa_addr || i->ifa_addr->sa_family != AF_INET) continue;
    const auto* in = reinterpret_cast<const sockaddr_in*>(i->ifa_addr);
    if ((ntohl(in->sin_addr.s_addr) >> 24) == 127) continue;
    char text[INET_ADDRSTRLEN];
    if (inet_ntop(AF_INET, &in->sin_addr, text, sizeof text)) found = text;
  }
  freeifaddrs(list);
  return found;
}

// Whether a TCP connection to address:port succeeds.
bool connects(const std::string& address, int port) {
  int s = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  inet_pton(AF_INET, address.c_str(), &a.sin_addr);
  const bool ok = connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0;
  close(s);
  return ok;
}

detail::StoreBytes bytes(const std::string& s) { return detail::StoreBytes(s.begin(), s.end()); }
std::chrono::steady_clock::time_point inSeconds(int s) { return std::chrono::steady_clock::now() + std::chrono::seconds(s); }

TEST(DistributedStore, ServesTheStoreOperations) {
  const int port = freePort();
  detail::RendezvousServer server("127.0.0.1", port, "s3cret");
  EXPECT_EQ(server.address(), "127.0.0.1:" + std::to_string(port));
  detail::RendezvousClient a("127.0.0.1", port, "s3cret", inSeconds(10)), b("127.0.0.1", port, "s3cret", inSeconds(10));
  a.set("k", bytes("v"));
  EXPECT_EQ(b.get("k", inSeconds(5)), bytes("v"));
  EXPECT_FALSE(b.tryGet("absent"));
  EXPECT_EQ(a.add("n", 2), 2);
  EXPECT_EQ(b.add("n", 3), 5);
  EXPECT_EQ(a.compareSet("c", {}, bytes("1")), bytes("1"));  // absent + empty expected: set
  EXPECT_EQ(a.compareSet("c", bytes("0"), bytes("2")), bytes("1"));  // not the expected value: unchanged
  EXPECT_EQ(a.compareSet("c", bytes("1"), bytes("2")), bytes("2"));
  EXPECT_EQ(a.compareSet("d", bytes("x"), bytes("y")), bytes("x"));  // absent, expected not empty: stays absent
  EXPECT_TRUE(a.check({"k", "n", "c"}));
  EXPECT_FALSE(a.check({"k", "d"}));
  EXPECT_EQ(a.numKeys(), 3);
  EXPECT_TRUE(a.deleteKey("k"));
  EXPECT_FALSE(a.deleteKey("k"));
  test::expectErrorContaining([&] { b.get("k", inSeconds(1)); }, {"timed out", "k"});
  std::thread later([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    a.set("late", bytes("x"));
  });
  EXPECT_EQ(b.get("late", inSeconds(10)), bytes("x"));  // a blocking get sees a key set meanwhile
  later.join();
}

TEST(DistributedStore, ListensOnlyOnTheMasterAddress) {
  const int port = freePort();
  detail::RendezvousServer server("127.0.0.1", port, "s3cret");
  // The system's own table of listening sockets: one, on 127.0.0.1 (0100007F as /proc writes it).
  EXPECT_EQ(listeningAddresses(port), std::vector<std::string>{"0100007F"});
  EXPECT_TRUE(connects("127.0.0.1", port));
  const std::string other = nonLoopbackAddress();
  if (other.empty()) GTEST_SKIP() << "this machine has no non-loopback IPv4 address to try the port on";
  EXPECT_FALSE(connects(other, port)) << "the rendezvous answered on " << other;
}

TEST(DistributedStore, APeerWithAWrongSecretIsRefused) {
  const int port = freePort();
  detail::RendezvousServer server("127.0.0.1", port, "s3cret");
  ::testing::internal::CaptureStderr();
  test::expectErrorContaining(
      [&] {
        detail::RendezvousClient stranger("127.0.0.1", port, "guess", inSeconds(10));
        stranger.set("nbtf/settings/0", bytes("poison"));
      },
      {"refused", "--dist-secret", "NBTF_DIST_SECRET"});
  // A peer that sends no handshake at all is refused as well.
  {
    int s = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
    ASSERT_EQ(connect(s, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    const char junk[] = "\xff\xff\xff\x7fGET / HTTP/1.0\r\n\r\n";
    ASSERT_GT(send(s, junk, sizeof junk - 1, 0), 0);
    char c;
    EXPECT_LE(recv(s, &c, 1, 0), 0) << "the server answered a peer without the secret";
    close(s);
  }
  const std::string warnings = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(warnings.find("refused the connection from 127.0.0.1:"), std::string::npos) << warnings;
  EXPECT_NE(warnings.find("wrong shared secret"), std::string::npos) << warnings;
  detail::RendezvousClient rank("127.0.0.1", port, "s3cret", inSeconds(10));
  EXPECT_FALSE(rank.check({"nbtf/settings/0"})) << "the refused peer set a key";
  EXPECT_EQ(rank.numKeys(), 0);
}

TEST(DistributedStore, APortInUseFailsAtOnceNamingIt) {
  const int port = freePort();
  const int busy = listenOn(port);
  ASSERT_GE(busy, 0);
  test::expectErrorContaining([&] { detail::RendezvousServer("127.0.0.1", port, "s3cret"); },
                              {"port " + std::to_string(port) + " on 127.0.0.1 is already in use"});
  close(busy);
}

TEST(DistributedStore, SecretsCompareExactly) {
  EXPECT_TRUE(detail::sameSecret("abc", "abc"));
  EXPECT_FALSE(detail::sameSecret("abd", "abc"));
  EXPECT_FALSE(detail::sameSecret("abcabc", "abc"));  // a repetition is not the secret
  EXPECT_FALSE(detail::sameSecret("ab", "abc"));
  EXPECT_FALSE(detail::sameSecret("", ""));
  EXPECT_EQ(detail::randomSecret().size(), 32u);
  EXPECT_NE(detail::randomSecret(), detail::randomSecret());
}

}  // namespace
}  // namespace nbtf
