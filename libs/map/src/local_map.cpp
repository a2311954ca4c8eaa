#include <mrpt/core/exceptions.h>
#include <mrpt/core/initializer.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/serialization/stl_serialization.h>
#include <rasterslam/map/keyframe.h>
#include <rasterslam/map/local_map.h>
#include <rasterslam/map/registration.h>

using namespace rasterslam;

IMPLEMENTS_SERIALIZABLE(LocalMap, mrpt::serialization::CSerializable, rasterslam)
IMPLEMENTS_SERIALIZABLE(LocalMapGraph, mrpt::serialization::CSerializable, rasterslam)

RASTERSLAM_REGISTER_CLASSES(register_rasterslam_map_classes)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::LocalMap));
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::LocalMapGraph));
}

uint8_t LocalMap::serializeGetVersion() const
{
	return 2;
}

void LocalMap::serializeTo(mrpt::serialization::CArchive& out) const
{
	out << id << session << keyframes << createdStamp << updatedStamp << online << xyz
	    << descriptors << observers << imagePng << imageResolution_m << imageExtent_m << baTracks
	    << baInitialRms_m << baFinalRms_m << surfaceCm << contextRings << contextSectors
	    << contextCells;
}

void LocalMap::serializeFrom(mrpt::serialization::CArchive& in, uint8_t version)
{
	switch (version)
	{
		case 0:
		case 1:
		case 2:
		{
			// The flag as its byte: a bool read from a damaged file could hold any value (found
			// by fuzz_map_store: undefined behaviour when used).
			uint8_t onlineByte = 0;
			in >> id >> session >> keyframes >> createdStamp >> updatedStamp >> onlineByte >> xyz >>
			    descriptors >> observers >> imagePng >> imageResolution_m >> imageExtent_m >>
			    baTracks >> baInitialRms_m >> baFinalRms_m;
			if (onlineByte > 1)
				THROW_EXCEPTION(mrpt::format("rasterslam::LocalMap: online flag %u is not 0 or 1",
				                             static_cast<unsigned>(onlineByte)));
			online = onlineByte != 0;
			surfaceCm.clear();
			if (version >= 1)
				in >> surfaceCm;
			contextRings = contextSectors = 0;
			contextCells.clear();
			if (version >= 2)
				in >> contextRings >> contextSectors >> contextCells;
			break;
		}
		default:
			MRPT_THROW_UNKNOWN_SERIALIZATION_VERSION(version);
	}
	const std::size_t n = observers.size();
	if (xyz.size() != 3 * n || descriptors.size() != 32 * n)
		THROW_EXCEPTION("rasterslam::LocalMap: inconsistent point arrays in the stream");
	if (surfaceCm.size() % 3 != 0)
		THROW_EXCEPTION(
		    "rasterslam::LocalMap: surface coordinates are not a whole number of points");
	const std::size_t cells = std::size_t{contextRings} * contextSectors;
	if ((cells == 0) != contextCells.empty() ||
	    (cells != 0 && contextCells.size() != cells * keyframes.size()))
		THROW_EXCEPTION(
		    mrpt::format("rasterslam::LocalMap %llu: %zu polar-context cells for %u x %u cells and "
		                 "%zu keyframes",
		                 static_cast<unsigned long long>(id), contextCells.size(),
		                 static_cast<unsigned>(contextRings), static_cast<unsigned>(contextSectors),
		                 keyframes.size()));
	if (keyframes.empty() || keyframes.size() > kMaxKeyframes)
		THROW_EXCEPTION(mrpt::format("rasterslam::LocalMap %llu: %zu keyframes (expected 1..%zu)",
		                             static_cast<unsigned long long>(id), keyframes.size(),
		                             kMaxKeyframes));
}

int LocalMap::keyframeIndex(uint64_t kf) const
{
	for (std::size_t i = 0; i < keyframes.size(); i++)
		if (keyframes[i] == kf)
			return static_cast<int>(i);
	return -1;
}

std::size_t LocalMap::memoryBytes() const
{
	return sizeof(*this) + keyframes.capacity() * 8 + xyz.capacity() * 4 + descriptors.capacity() +
	       observers.capacity() * 4 + imagePng.capacity() + surfaceCm.capacity() * 2 +
	       contextCells.capacity();
}

bool LocalMap::operator==(const LocalMap& o) const
{
	return id == o.id && session == o.session && keyframes == o.keyframes &&
	       createdStamp == o.createdStamp && updatedStamp == o.updatedStamp && online == o.online &&
	       xyz == o.xyz && descriptors == o.descriptors && observers == o.observers &&
	       imagePng == o.imagePng && imageResolution_m == o.imageResolution_m &&
	       imageExtent_m == o.imageExtent_m && baTracks == o.baTracks &&
	       baInitialRms_m == o.baInitialRms_m && baFinalRms_m == o.baFinalRms_m &&
	       surfaceCm == o.surfaceCm && contextRings == o.contextRings &&
	       contextSectors == o.contextSectors && contextCells == o.contextCells;
}

uint8_t LocalMapGraph::serializeGetVersion() const
{
	return 0;
}

void LocalMapGraph::serializeTo(mrpt::serialization::CArchive& out) const
{
	out << static_cast<uint64_t>(edges.size());
	for (const auto& e : edges)
		out << e.from << e.to << static_cast<uint8_t>(e.kind) << e.stamp;
}

void LocalMapGraph::serializeFrom(mrpt::serialization::CArchive& in, uint8_t version)
{
	switch (version)
	{
		case 0:
		{
			uint64_t n = 0;
			in >> n;
			edges.clear();
			for (uint64_t i = 0; i < n; i++)
			{
				Edge e;
				uint8_t kind = 0;
				in >> e.from >> e.to >> kind >> e.stamp;
				if (kind > 2)
					THROW_EXCEPTION(
					    mrpt::format("rasterslam::LocalMapGraph: unknown edge kind %u", kind));
				e.kind = static_cast<EdgeKind>(kind);
				edges.push_back(e);
			}
			break;
		}
		default:
			MRPT_THROW_UNKNOWN_SERIALIZATION_VERSION(version);
	}
}

void LocalMapGraph::add(uint64_t from, uint64_t to, EdgeKind kind, double stamp)
{
	edges.push_back({from, to, kind, stamp});
}

std::size_t LocalMapGraph::count(EdgeKind kind) const
{
	std::size_t n = 0;
	for (const auto& e : edges)
		n += e.kind == kind;
	return n;
}

const char* rasterslam::toString(LocalMapGraph::EdgeKind k)
{
	switch (k)
	{
		case LocalMapGraph::EdgeKind::Sequential:
			return "sequential";
		case LocalMapGraph::EdgeKind::Loop:
			return "loop";
		case LocalMapGraph::EdgeKind::Relocalization:
			return "relocalization";
	}
	return "?";
}
