// Device choice: the devices that exist are listed, a device asked for that does not exist is
// refused with that list (never a silent fallback), odd selectors do not throw.
#include <gtest/gtest.h>

#include <string>

#include "host/opencl_runtime.h"

namespace hnnstereo::ocl {
namespace {

TEST(DeviceSelection, ListsTheDevicesThatExist) {
  std::string why_none;
  const std::vector<DeviceInfo> devices = ListDevices(&why_none);
  if (devices.empty()) {
    EXPECT_FALSE(why_none.empty());
    EXPECT_EQ(DescribeDevices(devices), "no OpenCL device is installed");
    GTEST_SKIP() << "no OpenCL device: " << why_none;
  }
  for (const DeviceInfo& info : devices) {
    EXPECT_FALSE(info.device_name.empty());
    EXPECT_FALSE(info.platform_name.empty());
    EXPECT_TRUE(info.type == "gpu" || info.type == "cpu" || info.type == "accelerator" ||
                info.type == "other");
    EXPECT_GT(info.compute_units, 0u);
  }
  const std::string description = DescribeDevices(devices);
  EXPECT_NE(description.find("platform 0 '"), std::string::npos) << description;
  EXPECT_NE(description.find("device 0 '" + devices.front().device_name + "'"), std::string::npos)
      << description;
  // The first device by index and by a part of its name.
  DeviceSelection by_index;
  by_index.device = "0";
  std::string why_not;
  EXPECT_NE(Runtime::Create(by_index, &why_not), nullptr) << why_not;
  DeviceSelection by_name;
  by_name.device = devices.front().device_name.substr(0, 4);
  EXPECT_NE(Runtime::Create(by_name, &why_not), nullptr) << why_not;
}

TEST(DeviceSelection, AMissingDeviceIsRefusedWithTheList) {
  for (const std::string selector : {"no-such-device", "99", "99999999999999999999"}) {
    DeviceSelection selection;
    selection.device = selector;
    EXPECT_FALSE(selection.empty());
    std::string why_not;
    EXPECT_EQ(Runtime::Create(selection, &why_not), nullptr) << selector;
    if (!ListDevices().empty()) {
      EXPECT_NE(why_not.find("no OpenCL device matches device '" + selector + "'"),
                std::string::npos)
          << why_not;
      EXPECT_NE(why_not.find("there are: platform 0"), std::string::npos) << why_not;
    }
  }
  EXPECT_TRUE(DeviceSelection{}.empty());
}

}  // namespace
}  // namespace hnnstereo::ocl
