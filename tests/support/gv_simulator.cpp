// Starting and stopping Aravis's GigE Vision camera simulator.
#include "gv_simulator.h"

#include <arv.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace mixray::test {

bool GvSimulator::installed() {
    return access(kGvSimulator, X_OK) == 0;
}

bool GvSimulator::start(int lost_per_thousand, const std::string& genicam,
                        const std::string& netns) {
    const std::string lost = std::to_string(lost_per_thousand);
    std::vector<const char*> argv;
    if (!netns.empty())
        argv = {"/usr/bin/ip", "netns", "exec", netns.c_str()};
    for (const char* arg :
         {kGvSimulator, "-i", kGvSimulatorAddress, "-s", kGvSimulatorSerial, "-r"})
        argv.push_back(arg);
    argv.push_back(lost.c_str());
    if (!genicam.empty()) {
        argv.push_back("-g");
        argv.push_back(genicam.c_str());
    }
    argv.push_back(nullptr);
    if (posix_spawn(&pid_, argv[0], nullptr, nullptr, const_cast<char**>(argv.data()), environ) !=
        0) {
        pid_ = -1;
        return false;
    }
    return true;
}

void GvSimulator::kill() {
    if (pid_ <= 0)
        return;
    ::kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
}

std::string genicamWith(const std::string& nodes) {
    ArvFakeCamera* fake = arv_fake_camera_new("DESC");
    size_t size = 0;
    const char* xml = arv_fake_camera_get_genicam_xml(fake, &size);
    std::string text(xml ? xml : "", xml ? size : 0);
    g_object_unref(fake);
    const size_t end = text.rfind("</RegisterDescription>");
    if (end == std::string::npos)
        return {};
    text.insert(end, nodes);
    return text;
}

std::string writeGenicam(const std::string& xml, const std::string& name) {
    const std::string path = ::testing::TempDir() + name;
    std::ofstream out(path, std::ios::binary);
    out << xml;
    return out.good() ? path : std::string();
}

// Aravis's fake camera description with GigE Vision's IEEE 1588 features added: GevIEEE1588
// on a free register of the simulator's memory, and GevIEEE1588Status reading the same
// register, Disabled (0) or Listening (1), which is what a PTP port reports while it hears no
// grandmaster. The simulator keeps registers it does not know as plain memory, so it stands in
// for a camera that has the features; it runs no PTP, and its clock stays the system clock.
std::string genicamWithPtp() {
    return genicamWith(R"(
<Boolean Name="GevIEEE1588" NameSpace="Standard">
  <pValue>MixrayPtpRegister</pValue>
</Boolean>
<Enumeration Name="GevIEEE1588Status" NameSpace="Standard">
  <EnumEntry Name="Disabled" NameSpace="Standard"><Value>0</Value></EnumEntry>
  <EnumEntry Name="Listening" NameSpace="Standard"><Value>1</Value></EnumEntry>
  <pValue>MixrayPtpRegister</pValue>
</Enumeration>
<IntReg Name="MixrayPtpRegister" NameSpace="Custom">
  <Address>0xb000</Address>
  <Length>4</Length>
  <AccessMode>RW</AccessMode>
  <pPort>Device</pPort>
  <Sign>Unsigned</Sign>
  <Endianess>BigEndian</Endianess>
</IntReg>
)");
}

Result<std::unique_ptr<Device>> openWhenUp(DeviceBackend& backend, const DeviceConfig& config) {
    Result<std::unique_ptr<Device>> opened{ErrorCode::kNotFound, "not tried"};
    for (int attempt = 0; attempt < 40; ++attempt) {
        opened = backend.open(config);
        if (opened || opened.status().code() != ErrorCode::kNotFound)
            return opened;
        std::this_thread::sleep_for(std::chrono::milliseconds(250));
    }
    return opened;
}

}  // namespace mixray::test
