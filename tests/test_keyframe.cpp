// Keyframes (the pose-graph nodes of the tracking) through MRPT serialization: a round trip,
// an unknown version and inconsistent feature arrays.
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CArchive.h>
#include <rasterslam/map/keyframe.h>

#include <string>

#include "test_support.h"

using namespace rasterslam;

TEST(Keyframe, SerializationRoundTrip)
{
	Keyframe k;
	k.id = 12;
	k.session = 3;
	k.scanIndex = 345;
	k.stamp = 1.7e9 + 0.25;
	k.pose = mrpt::poses::CPose3D(1, -2, 0.5, 0.3, -0.02, 0.01);
	for (int i = 0; i < 5; i++)
	{
		k.u.push_back(10.5f * i);
		k.v.push_back(3.25f * i);
		k.angle.push_back(12.0f * i);
		k.response.push_back(0.001f * i);
		k.octave.push_back(static_cast<uint8_t>(i));
		for (int c = 0; c < 3; c++)
			k.xyz.push_back(float(i) + 0.1f * c);
		for (int b = 0; b < 32; b++)
			k.descriptors.push_back(static_cast<uint8_t>(i * 32 + b));
	}
	k.groundValid = true;
	k.groundN[0] = 0.6f;
	k.groundN[2] = 0.8f;
	k.groundD = 1.73f;
	mrpt::io::CMemoryStream buf;
	auto arch = mrpt::serialization::archiveFrom(buf);
	arch << k;
	buf.Seek(0);
	const auto obj = arch.ReadObject();
	const auto back = std::dynamic_pointer_cast<Keyframe>(obj);
	ASSERT_TRUE(back);
	EXPECT_EQ(back->size(), 5u);
	EXPECT_TRUE(*back == k);
	Keyframe other = k;
	other.descriptors[40] ^= 1;
	EXPECT_FALSE(other == k);  // operator== looks at the descriptors
	other = k;
	other.groundD = 1.5f;
	EXPECT_FALSE(other == k);  // and at the ground plane

	// An unknown version: the byte after the class name in MRPT's object header.
	const std::string name = "rasterslam::Keyframe";
	auto* bytes = static_cast<uint8_t*>(buf.getRawBufferData());
	const std::string raw(reinterpret_cast<const char*>(bytes), buf.getTotalBytesCount());
	const auto at = raw.find(name);
	ASSERT_NE(at, std::string::npos);
	ASSERT_EQ(bytes[at + name.size()], 2);  // version 2
	bytes[at + name.size()] = 9;
	buf.Seek(0);
	EXPECT_ANY_THROW(arch.ReadObject());

	// Inconsistent arrays (one descriptor byte short) are refused on reading.
	Keyframe bad = k;
	bad.descriptors.pop_back();
	mrpt::io::CMemoryStream buf2;
	auto arch2 = mrpt::serialization::archiveFrom(buf2);
	arch2 << bad;
	buf2.Seek(0);
	EXPECT_ANY_THROW(arch2.ReadObject());
	Keyframe bad2 = k;
	bad2.xyz.push_back(0);
	mrpt::io::CMemoryStream buf3;
	auto arch3 = mrpt::serialization::archiveFrom(buf3);
	arch3 << bad2;
	buf3.Seek(0);
	EXPECT_ANY_THROW(arch3.ReadObject());
	// A ground flag other than 0 or 1 is refused (fuzz_map_store: reading 220 into a bool).
	{
		mrpt::io::CMemoryStream b5;
		auto a5 = mrpt::serialization::archiveFrom(b5);
		a5 << k;
		auto* p5 = static_cast<uint8_t*>(b5.getRawBufferData());
		const std::string raw5(reinterpret_cast<const char*>(p5), b5.getTotalBytesCount());
		const float plane[4] = {k.groundN[0], k.groundN[1], k.groundN[2], k.groundD};
		const auto at5 = raw5.find(std::string(reinterpret_cast<const char*>(plane), 16));
		ASSERT_NE(at5, std::string::npos);
		ASSERT_GT(at5, 0u);
		ASSERT_EQ(p5[at5 - 1], 1);  // the flag
		p5[at5 - 1] = 220;
		b5.Seek(0);
		EXPECT_ANY_THROW(a5.ReadObject());
	}
	// A ground normal that is not unit is refused.
	Keyframe bad3 = k;
	bad3.groundN[2] = 2;
	mrpt::io::CMemoryStream buf4;
	auto arch4 = mrpt::serialization::archiveFrom(buf4);
	arch4 << bad3;
	buf4.Seek(0);
	EXPECT_ANY_THROW(arch4.ReadObject());
}
