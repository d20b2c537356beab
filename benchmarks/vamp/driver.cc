// The outside reference of `bench mbm`: VAMP 0.6.4's RRTC (its headers, built by build.sh) on
// problems exported from a manyhands problems.json by problems_to_txt.py.
// usage: driver ROBOT PROBLEMS.txt TRIALS RANGE   (ROBOT: panda, ur5, fetch or baxter)
// prints one line per trial: set, index, solved (0/1), iterations, planning nanoseconds.
// The Halton sampler is reset before each problem (as VAMP's scripts/evaluate_mbm.py does).
#include <vector>
#include <array>
#include <string>
#include <fstream>
#include <sstream>
#include <iostream>

#include <Eigen/Geometry>
#include <vamp/collision/factory.hh>
#include <vamp/planning/validate.hh>
#include <vamp/planning/rrtc.hh>
#include <vamp/robots/panda.hh>
#include <vamp/robots/ur5.hh>
#include <vamp/robots/fetch.hh>
#include <vamp/robots/baxter.hh>
#include <vamp/random/halton.hh>

static constexpr const std::size_t rake = vamp::FloatVectorWidth;
using EnvironmentInput = vamp::collision::Environment<float>;
using EnvironmentVector = vamp::collision::Environment<vamp::FloatVector<rake>>;

struct Problem
{
    std::string set;
    int index = 0;
    std::vector<float> start;
    std::vector<std::vector<float>> goals;
    EnvironmentInput env;
};

static auto read_problems(const char *path) -> std::vector<Problem>
{
    std::ifstream in(path);
    std::vector<Problem> out;
    std::string line;
    Problem cur;
    while (std::getline(in, line))
    {
        std::istringstream ss(line);
        std::string tag;
        ss >> tag;
        auto floats = [&ss]()
        {
            std::vector<float> v;
            float x;
            while (ss >> x)
                v.push_back(x);
            return v;
        };
        if (tag == "P")
        {
            cur = Problem{};
            ss >> cur.set >> cur.index;
        }
        else if (tag == "S")
            cur.start = floats();
        else if (tag == "G")
            cur.goals.push_back(floats());
        else if (tag == "sphere")
        {
            auto v = floats();
            cur.env.spheres.emplace_back(vamp::collision::factory::sphere::flat(v[0], v[1], v[2], v[3]));
        }
        else if (tag == "box" or tag == "cyl")
        {
            auto v = floats();
            Eigen::Quaternionf q(v[6], v[3], v[4], v[5]);
            Eigen::Matrix3f m = q.normalized().toRotationMatrix();
            if (tag == "box")
            {
                cur.env.cuboids.emplace_back(vamp::collision::Cuboid<float>(
                    v[0], v[1], v[2],
                    m(0, 0), m(1, 0), m(2, 0),
                    m(0, 1), m(1, 1), m(2, 1),
                    m(0, 2), m(1, 2), m(2, 2),
                    v[7], v[8], v[9]));
            }
            else
            {
                Eigen::Vector3f c(v[0], v[1], v[2]);
                Eigen::Vector3f p1 = c + m * Eigen::Vector3f(0, 0, v[8] / 2);
                Eigen::Vector3f p2 = c - m * Eigen::Vector3f(0, 0, v[8] / 2);
                cur.env.cylinders.emplace_back(vamp::collision::factory::cylinder::endpoints::flat(
                    p1[0], p1[1], p1[2], p2[0], p2[1], p2[2], v[7]));
            }
        }
        else if (tag == "E")
        {
            cur.env.sort();
            out.push_back(cur);
        }
    }
    return out;
}

template <typename Robot>
static auto run(const std::vector<Problem> &problems, int trials, float range) -> int
{
    using RRTC = vamp::planning::RRTC<Robot, rake, Robot::resolution>;
    vamp::planning::RRTCSettings settings;
    settings.range = range;
    settings.max_iterations = 1000000;
    settings.max_samples = 1000000;
    auto rng = std::make_shared<vamp::rng::Halton<Robot>>();
    for (const auto &p : problems)
    {
        auto env_v = EnvironmentVector(p.env);
        typename Robot::ConfigurationArray s{};
        for (std::size_t i = 0; i < Robot::dimension; ++i)
            s[i] = p.start[i];
        std::vector<typename Robot::Configuration> goals;
        for (const auto &g : p.goals)
        {
            typename Robot::ConfigurationArray ga{};
            for (std::size_t i = 0; i < Robot::dimension; ++i)
                ga[i] = g[i];
            goals.emplace_back(ga);
        }
        rng->reset();
        for (int t = 0; t < trials; ++t)
        {
            auto result = RRTC::solve(typename Robot::Configuration(s), goals, env_v, settings, rng);
            std::cout << p.set << '\t' << p.index << '\t' << (result.path.size() > 0) << '\t'
                      << result.iterations << '\t' << result.nanoseconds << '\n';
        }
    }
    return 0;
}

auto main(int argc, char **argv) -> int
{
    if (argc < 5)
    {
        std::cerr << "usage: driver ROBOT PROBLEMS.txt TRIALS RANGE\n";
        return 2;
    }
    const std::string robot = argv[1];
    auto problems = read_problems(argv[2]);
    if (problems.empty())
    {
        std::cerr << "no problems read from " << argv[2] << "\n";
        return 2;
    }
    const int trials = std::stoi(argv[3]);
    const float range = std::stof(argv[4]);
    if (robot == "panda")
        return run<vamp::robots::Panda>(problems, trials, range);
    if (robot == "ur5")
        return run<vamp::robots::UR5>(problems, trials, range);
    if (robot == "fetch")
        return run<vamp::robots::Fetch>(problems, trials, range);
    if (robot == "baxter")
        return run<vamp::robots::Baxter>(problems, trials, range);
    std::cerr << "unknown robot\n";
    return 2;
}
