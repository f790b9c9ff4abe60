"""`trials log train-detector BAG... --out FILE`: train the learned leg detector from labelled logs."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from trials import option_types as types


def register(group: argparse._SubParsersAction) -> None:
    parser = group.add_parser(
        "train-detector",
        help="train the leg detector from logs with labelled legs, with cross-validated precision and recall",
        description="Train the leg classifier (gradient-boosted trees on segment features) from logs whose "
        "legs are labelled (geometry_msgs/PoseArray, one pose per leg), plus logs recorded with nobody present "
        "(--empty) and logs of a robot standing still among passers-by (--standing), whose legs are the leg-wide "
        "segments in front of each beam's background. Unmatched segments within --ignore-radius of a label are left "
        "out; the rest are negatives. Each log with legs is also trained on as a laser of half its resolution sees "
        "it (once more with its segments taken for twice as far) and with beams lost (--no-augment: not). "
        "Prints precision and recall cross-validated by whole log and by blocks of time, under that protocol "
        "and strictly (every unlabelled segment a negative), over every log's segments and over the labelled and "
        "the standing logs' alone, for the classifier alone and followed by static-world "
        "rejection (each log's own occupancy grid from its earlier scans, each scan placed by scan matching), and writes the detector as an .npz file with its "
        "training record for `trials log track --detector`.",
    )
    parser.add_argument("bags", nargs="+", type=types.input_file, metavar="BAG", help="logs with labelled legs")
    parser.add_argument("--empty", nargs="+", type=types.input_file, default=[], metavar="BAG",
                        help="logs recorded with nobody present: every segment is a negative example")
    parser.add_argument("--standing", nargs="+", type=types.input_file, default=[], metavar="BAG",
                        help="logs of a robot standing still while people pass: legs labelled by background subtraction")
    parser.add_argument("--out", type=types.output_file, required=True, metavar="FILE", help="the detector file to write (.npz)")
    parser.add_argument("--scan-topic", metavar="TOPIC", help="LaserScan topic of the labelled and the standing logs (default: their only one)")
    parser.add_argument("--labels-topic", metavar="TOPIC", help="PoseArray topic of the labelled legs (default: the only one)")
    parser.add_argument("--recall", type=types.number(0.0, 1.0, above=True), default=0.9,
                        help="the threshold keeps this share of the labelled legs through the classifier and the static "
                        "world in cross-validation (default 0.9)")
    parser.add_argument("--ignore-radius", type=types.number(0.0, 10.0), default=1.0, metavar="M",
                        help="unmatched segments this close to a label are neither legs nor negatives (default 1.0)")
    parser.add_argument("--block", type=types.number(0.0, 3600.0, above=True), default=10.0, metavar="S",
                        help="seconds per time block of the cross-validation (default 10)")
    parser.add_argument("--seed", type=types.seed, default=0, help="seeds the boosting and the folds (default 0)")
    parser.add_argument("--no-scan-odometry", dest="scan_odometry", action="store_false",
                        help="keep each sensor's static-world grid in the sensor's own frame instead of placing its "
                        "scans by scan matching (the logs carry no odometry; a moving robot then keeps little static)")
    parser.add_argument("--no-augment", dest="augment", action="store_false",
                        help="train on the logs as recorded only, not also on their copies with every other beam and "
                        "with lost beams")
    model = parser.add_argument_group("the model (defaults: robot_logs.leg_training.TrainingSettings)")
    model.add_argument("--trees", type=types.whole(1), help="boosting iterations (default 200)")
    model.add_argument("--leaves", type=types.whole(2), help="leaves per tree (default 31)")
    model.add_argument("--min-leaf", type=types.whole(1), metavar="N", help="fewest segments in a leaf (default 50)")
    model.add_argument("--l2", type=types.number(0.0, 1e6), help="L2 penalty on leaf values (default 1)")
    model.add_argument("--balanced", action="store_true", default=None,
                       help="weight legs and other segments equally (default: no class weights)")
    parser.set_defaults(handler=train_detector)


def train_detector(args: argparse.Namespace) -> int:
    from robot_logs.leg_training import TrainingSettings, collect, train, validate
    from robot_logs.topics import TopicNames

    model = {"trees": args.trees, "leaves": args.leaves, "min_leaf": args.min_leaf, "l2": args.l2, "balanced": args.balanced}
    settings = TrainingSettings(ignore_radius=args.ignore_radius, block_s=args.block, recall=args.recall, seed=args.seed,
                                scan_odometry=args.scan_odometry, augment=args.augment,
                                **{name: value for name, value in model.items() if value is not None})
    topics = TopicNames(scan=args.scan_topic, people=args.labels_topic)
    data = collect(args.bags, args.empty, topics, settings, standing=args.standing)
    recorded = ~data.augmented
    sys.stderr.write(f"{int(recorded.sum())} segments, {int(data.is_leg[recorded].sum())} at legs, "
                     f"{int(data.ignored[recorded].sum())} ignored (near a label or partly in front of a standing "
                     f"log's background), from {len(data.logs)} logs "
                     f"(and {int(data.augmented.sum())} of their augmented copies)\n")
    levels, validation, false_positives = validate(data, settings)
    classifier = train(data, levels, settings, validation)
    classifier.save(Path(args.out))
    held_out = "log" if "logs" in validation else "time blocks"
    print(f"leg threshold {levels[0]:.3f} (the classifier followed by the static world keeps {settings.recall:.0%} of "
          f"the labelled legs there), confirming {levels[1]:.3f} and protecting {levels[2]:.3f} (probabilities "
          f"{settings.confirm_recall:.0%} and {settings.protect_recall:.0%} of them reach); held out by {held_out}")
    print(f"cross-validated precision / recall of the segments called legs (probability >= {levels[0]:.3f}):\n"
          f"  protocol: unmatched segments within {settings.ignore_radius:g} m of a label left out; "
          "strict: every unlabelled segment a negative\n"
          "  + static world: no segment on a cell that its log's own occupancy grid holds static after the earlier "
          "scans (the grid `trials log track` keeps)")
    print(f"{'held out by':<13}{'segments of':<16}{'detection':<29}{'protocol':<17}strict")
    for design in ("logs", "time blocks"):
        for scope, logs in (("", "every log"), (", labelled logs", "labelled logs"), (", standing logs", "standing logs")):
            for stage in ("", ", static world"):
                name = f"{design}{scope}{stage}"
                if name not in validation:
                    continue
                protocol, strict = validation[name], validation[f"{name}, strict"]
                print(f"{design:<13}{logs:<16}{'classifier + static world' if stage else 'classifier alone':<29}"
                      f"{protocol.precision:.3f} / {protocol.recall:.3f}    {strict.precision:.3f} / {strict.recall:.3f}")
    legs = validation[next(iter(validation))]
    print(f"({legs.legs} labelled legs among {legs.segments} segments under the protocol, "
          f"{validation[next(iter(validation)) + ', strict'].segments} strictly)")
    print(f"segments wrongly called legs under the protocol, held out by {held_out}, and those on the static world:")
    for log in false_positives:
        print(f"  {log.file:<32}{log.called:>6}{log.on_static:>6}")
    unplaced = {str(log["file"]): log["unplaced"] for log in data.logs if log["unplaced"]}
    if unplaced:
        print("scans scan matching could not place (nothing static on them): "
              + ", ".join(f"{file} {count}" for file, count in unplaced.items()))
    print(f"detector -> {args.out}")
    return 0
