#include "launcher/hosts_file.h"

#include <gtest/gtest.h>

#include <string>

#include "launcher/remote_host.h"

namespace shoal {
namespace {

/// The message of the HostsFileError that parsing `text` throws ("" if none).
std::string ErrorOf(const std::string& text) {
  try {
    ParseHostsFile(text, "dir/hosts.toml");
  } catch (const HostsFileError& e) {
    return e.what();
  }
  return "";
}

constexpr const char* kThreeHosts =
    "[[host]]\n"                                        // 1
    "name = \"h1\"\n"                                   // 2
    "prefix = [\"ip\", \"netns\", \"exec\", \"h1\"]\n"  // 3
    "interface = \"veth1\"\n"                           // 4
    "[[host]]\n"                                        // 5
    "name = \"h2\"\n"                                   // 6
    "prefix = [\"ip\", \"netns\", \"exec\", \"h2\"]\n"  // 7
    "[[host]]\n"                                        // 8
    "name = \"rack3\"\n"                                // 9
    "prefix = [\"/usr/bin/ssh\", \"-o\", \"BatchMode=yes\", \"rack3\"]\n";  // 10

TEST(HostsFile, ReadsHostsBusAndPlacement) {
  const HostsFile h = ParseHostsFile(
      std::string(kThreeHosts) +
          "[bus]\nttl = 2\n"
          "[placement]\nlogger = \"h1\"\nemulator = \"h1\"\nleader = \"h2\"\n"
          "vehicles = { h2 = [1, \"3-5\"], rack3 = [2] }\n",
      "dir/hosts.toml");
  ASSERT_EQ(h.hosts.size(), 4u);  // "local" first, implicit
  EXPECT_EQ(h.hosts[0].name, "local");
  EXPECT_TRUE(h.hosts[0].prefix.empty());
  EXPECT_EQ(h.hosts[1].interface, "veth1");
  EXPECT_EQ(h.hosts[1].line, 1);
  EXPECT_FALSE(h.hosts[1].remote_shell);
  EXPECT_TRUE(h.hosts[3].remote_shell);  // ssh: its arguments go through a shell there
  EXPECT_EQ(h.ttl, 2);
  EXPECT_EQ(h.HostOf(HostRole::kLogger).name, "h1");
  EXPECT_EQ(h.HostOf(HostRole::kEmulator).name, "h1");
  EXPECT_EQ(h.HostOfVehicle(0).name, "h2");
  EXPECT_EQ(h.HostOfVehicle(1).name, "h2");
  EXPECT_EQ(h.HostOfVehicle(2).name, "rack3");
  EXPECT_EQ(h.HostOfVehicle(4).name, "h2");
  EXPECT_EQ(h.HostOfVehicle(6).name, "local");  // not placed: the default host
  EXPECT_EQ(CheckPlacement(h, 6), "");
  EXPECT_EQ(h.UsedHosts(6).size(), 4u);
  EXPECT_EQ(h.UsedHosts(5).size(), 3u);
}

TEST(HostsFile, DefaultsAndTheDefaultHost) {
  const HostsFile empty = ParseHostsFile("", "h.toml");
  EXPECT_EQ(empty.ttl, 1);  // crosses a bridge
  ASSERT_EQ(empty.hosts.size(), 1u);
  EXPECT_EQ(empty.HostOfVehicle(3).name, "local");
  const HostsFile h = ParseHostsFile(std::string(kThreeHosts) +
                                         "[placement]\ndefault = \"h2\"\nvehicles = { h1 = [1] }\n",
                                     "h.toml");
  EXPECT_EQ(h.HostOf(HostRole::kLogger).name, "h2");
  EXPECT_EQ(h.HostOfVehicle(1).name, "h1");
  EXPECT_EQ(h.HostOfVehicle(2).name, "h2");
  // A host named "local" may be given explicitly, e.g. for its interface.
  const HostsFile local = ParseHostsFile("[[host]]\nname = \"local\"\ninterface = \"eth0\"\n", "h.toml");
  ASSERT_EQ(local.hosts.size(), 1u);
  EXPECT_EQ(local.hosts[0].interface, "eth0");
}

TEST(HostsFile, PlacementErrorsNameTheLine) {
  EXPECT_EQ(ErrorOf(std::string(kThreeHosts) + "[placement]\nleader = \"h9\"\n"),
            "dir/hosts.toml:12: placement.leader: unknown host \"h9\"; the hosts are: local, h1, "
            "h2, rack3 (define others with [[host]])");
  EXPECT_EQ(ErrorOf(std::string(kThreeHosts) + "[placement]\nvehicles = { h2 = [1], h7 = [2] }\n"),
            "dir/hosts.toml:12: placement.vehicles.h7: unknown host \"h7\"; the hosts are: local, "
            "h1, h2, rack3 (define others with [[host]])");
  EXPECT_EQ(ErrorOf(std::string(kThreeHosts) +
                    "[placement.vehicles]\nh1 = [1, 2]\nh2 = [\"2-4\"]\n"),
            "dir/hosts.toml:13: placement.vehicles.h2: vehicle 2 is placed twice (also on host "
            "\"h1\", line 12) (got \"2-4\"); place every vehicle once");
  EXPECT_NE(ErrorOf(std::string(kThreeHosts) + "[placement]\nvehicles = { h1 = [3, 3] }\n")
                .find("vehicle 3 is placed twice"),
            std::string::npos);
  const HostsFile h = ParseHostsFile(std::string(kThreeHosts) +
                                         "[placement]\nvehicles = { h1 = [1], h2 = [\"7-9\"] }\n",
                                     "dir/hosts.toml");
  EXPECT_EQ(CheckPlacement(h, 8),
            "dir/hosts.toml:12: placement.vehicles.h2: vehicle 9 is not in the scenario (its "
            "vehicles are 1 to 8); place only those");
}

TEST(HostsFile, BadValuesAreLocatedErrors) {
  EXPECT_EQ(ErrorOf("[[host]]\nname = \"h1\"\nprefx = [\"ssh\"]\n"),
            "dir/hosts.toml:3: host[0].prefx: unknown key; did you mean 'prefix'?");
  EXPECT_EQ(ErrorOf("[hosts]\n"),
            "dir/hosts.toml:1: hosts: unknown key; did you mean 'host'?");
  EXPECT_EQ(ErrorOf("[[host]]\nprefix = [\"ssh\", \"r\"]\n"),
            "dir/hosts.toml:1: host[0]: has no name; add name = \"h2\"");
  EXPECT_EQ(ErrorOf("[[host]]\nname = \"a b\"\n"),
            "dir/hosts.toml:2: host[0].name: must be 1-64 letters, digits, '_', '-' or '.' (got "
            "\"a b\"); name = \"rack2\"");
  EXPECT_EQ(ErrorOf("[[host]]\nname = \"h\"\n[[host]]\nname = \"h\"\n"),
            "dir/hosts.toml:3: host[1].name: host \"h\" is defined twice (first at line 1); give "
            "each host its own name");
  EXPECT_EQ(ErrorOf("[[host]]\nname = \"h\"\nprefix = \"ssh h\"\n"),
            "dir/hosts.toml:3: host[0].prefix: must be a list of strings (got \"ssh h\"); prefix "
            "= [\"ssh\", \"-o\", \"BatchMode=yes\", \"rack2\"]");
  EXPECT_NE(ErrorOf("[[host]]\nname = \"local\"\nprefix = [\"ssh\", \"x\"]\n")
                .find("dir/hosts.toml:3: host[0].prefix: must be empty for the host named \"local\""),
            std::string::npos);
  EXPECT_EQ(ErrorOf("[bus]\nttl = 256\n"),
            "dir/hosts.toml:2: bus.ttl: must be an integer from 0 to 255 (got 256); 1 crosses a "
            "bridge or switch, not a router");
  EXPECT_NE(ErrorOf("[bus]\nurl = \"udpm://239.255.76.67:7667?ttl=1\"\nttl = 1\n")
                .find("dir/hosts.toml:3: bus.ttl: cannot be given with bus.url"),
            std::string::npos);
  EXPECT_NE(ErrorOf("[bus]\nurl = \"udpm://239.255.76.67:7667?ttl=x\"\n").find("its ttl must be"),
            std::string::npos);
  EXPECT_NE(ErrorOf("[[host]]\nname = \"h\"\n[placement]\nvehicles = { h = [0] }\n")
                .find("dir/hosts.toml:4: placement.vehicles.h: is not a vehicle id (got 0)"),
            std::string::npos);
  EXPECT_NE(ErrorOf("[[host]]\nname = \"h\"\n[placement]\nvehicles = { h = [\"5-2\"] }\n")
                .find("is not a vehicle range (got \"5-2\")"),
            std::string::npos);
  EXPECT_NE(ErrorOf("[placement\n").find("dir/hosts.toml:1: TOML syntax error"), std::string::npos);
}

TEST(HostsFile, MissingFileIsAnError) {
  try {
    LoadHostsFile("/nonexistent/hosts.toml");
    FAIL() << "no error";
  } catch (const HostsFileError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/hosts.toml: cannot read hosts file"),
              std::string::npos)
        << e.what();
  }
}

TEST(HostsFile, UrlTtl) {
  EXPECT_EQ(UrlWithTtl("udpm://239.255.76.67:7667?ttl=0&recv_buf_size=4194304", 1),
            "udpm://239.255.76.67:7667?ttl=1&recv_buf_size=4194304");
  EXPECT_EQ(UrlWithTtl("udpm://239.255.76.67:7667?recv_buf_size=8&ttl=0", 3),
            "udpm://239.255.76.67:7667?recv_buf_size=8&ttl=3");
  EXPECT_EQ(UrlWithTtl("udpm://239.255.76.67:7667", 1), "udpm://239.255.76.67:7667?ttl=1");
  EXPECT_EQ(TtlOfUrl("udpm://239.255.76.67:7667"), 0);  // LCM's default
  EXPECT_EQ(TtlOfUrl("udpm://239.255.76.67:7667?recv_buf_size=8&ttl=1"), 1);
  EXPECT_EQ(TtlOfUrl("udpm://239.255.76.67:7667?ttl=one"), -1);
  EXPECT_EQ(GroupOfUrl("udpm://239.255.77.21:7669?ttl=1"), "239.255.77.21");
  EXPECT_EQ(GroupOfUrl("file:///tmp/x"), "");
}

TEST(RemoteHost, CommandQuotesOnlyForARemoteShell) {
  Host netns;
  netns.prefix = {"ip", "netns", "exec", "h1"};
  const std::vector<std::string> argv = {"/b/shoal_vehicle", "--set=name='x y'"};
  const std::vector<std::string> a = HostCommand(netns, argv, "/w d");
  ASSERT_EQ(a.size(), 11u);
  EXPECT_EQ(a[4], "sh");
  EXPECT_EQ(a[5], "-c");
  EXPECT_EQ(a[8], "/w d");
  EXPECT_EQ(a[10], "--set=name='x y'");
  Host ssh = netns;
  ssh.prefix = {"ssh", "rack2"};
  ssh.remote_shell = true;
  const std::vector<std::string> b = HostCommand(ssh, argv, "/w d");
  EXPECT_EQ(b[2], "'sh'");
  EXPECT_EQ(b[6], "'/w d'");
  EXPECT_EQ(b[8], "'--set=name='\\''x y'\\'''");
  EXPECT_EQ(b.size(), a.size() - 2);
}

}  // namespace
}  // namespace shoal
