// Reading the JSON the programs print (nlohmann-json), for the tests.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <nlohmann/json.hpp>
#include <string>

namespace rasterslam::test
{
/** The one JSON object a program printed; an empty object (and a failed test naming the
 *  output) when it is not one. */
inline nlohmann::json parseJson(const std::string& out)
{
	try
	{
		return nlohmann::json::parse(out);
	}
	catch (const nlohmann::json::parse_error& e)
	{
		ADD_FAILURE() << "not one JSON object (" << e.what() << "):\n" << out;
		return nlohmann::json::object();
	}
}

/** The number at `key`, or at a JSON pointer ("/runs/0/total_ms/first"); NaN when it is
 *  missing, null or no number. */
inline double number(const nlohmann::json& j, const std::string& keyOrPath)
{
	const auto ptr = nlohmann::json::json_pointer(
	    keyOrPath.empty() || keyOrPath[0] == '/' ? keyOrPath : "/" + keyOrPath);
	return j.contains(ptr) && j.at(ptr).is_number() ? j.at(ptr).get<double>() : std::nan("");
}

/** The number `key` of the JSON object a program printed (see number()). */
inline double jsonNumber(const std::string& out, const std::string& key)
{
	return number(parseJson(out), key);
}

}  // namespace rasterslam::test
