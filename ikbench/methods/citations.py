"""Each kinematics library's own citation, as BibTeX (``CITATIONS.bib`` of ``recommend``).

One entry per library, keyed by the distribution name a method declares (``library``). Only
facts that are certain are written; where a venue or an author list is not, the entry is a
``@misc`` with the project's address (``url`` / ``howpublished``) instead of a guess.
"""

from __future__ import annotations

from collections.abc import Iterable

#: distribution -> BibTeX entry (the paper or software record the project asks users to cite)
BIBTEX: dict[str, str] = {
    "ikbench": """@misc{ikbench,
  title = {ikbench: robot-arm trajectories of a required shape, and kinematics methods
    compared on them},
  author = {{the ikbench authors}},
  year = {2026},
  note = {Version 0.4.0; see CITATION.cff},
  howpublished = {Python package ikbench}
}""",
    "pin": """@inproceedings{carpentier2019pinocchio,
  title = {The {Pinocchio} {C++} library: A fast and flexible implementation of rigid body
    dynamics algorithms and their analytical derivatives},
  author = {Carpentier, Justin and Saurel, Guilhem and Buondonno, Gabriele and Mirabel, Joseph
    and Lamiraux, Florent and Stasse, Olivier and Mansard, Nicolas},
  booktitle = {IEEE/SICE International Symposium on System Integration (SII)},
  year = {2019}
}""",
    "pytracik": """@inproceedings{beeson2015tracik,
  title = {{TRAC-IK}: An Open-Source Library for Improved Solving of Generic Inverse Kinematics},
  author = {Beeson, Patrick and Ames, Barrett},
  booktitle = {IEEE-RAS International Conference on Humanoid Robots (Humanoids)},
  year = {2015}
}""",
    "roboticstoolbox-python": """@inproceedings{corke2021rtb,
  title = {Not your grandmother's toolbox -- the {Robotics Toolbox} reinvented for {Python}},
  author = {Corke, Peter and Haviland, Jesse},
  booktitle = {IEEE International Conference on Robotics and Automation (ICRA)},
  year = {2021}
}""",
    "eaik": """@article{ostermeier2025eaik,
  title = {Automatic Geometric Decomposition for Analytical Inverse Kinematics},
  author = {Ostermeier, Daniel and K{\\"u}lz, Jonathan and Althoff, Matthias},
  journal = {IEEE Robotics and Automation Letters},
  year = {2025}
}""",
    "drake": """@misc{drake,
  title = {Drake: Model-based design and verification for robotics},
  author = {Tedrake, Russ and {the Drake Development Team}},
  year = {2019},
  url = {https://drake.mit.edu}
}""",
    "pin-pink": """@misc{pink,
  title = {Pink: Python inverse kinematics based on Pinocchio},
  author = {Caron, St{\\'e}phane and others},
  url = {https://github.com/stephane-caron/pink}
}""",
    "mink": """@misc{mink,
  title = {Mink: Python inverse kinematics based on {MuJoCo}},
  author = {Zakka, Kevin},
  url = {https://github.com/kevinzakka/mink}
}""",
    "almond-pyroki": """@misc{pyroki,
  title = {{PyRoki}: A Modular Toolkit for Robot Kinematic Optimization},
  author = {Kim, Chung Min and Yi, Brent and Choi, Hongsuk and Ma, Yi and Goldberg, Ken
    and Kanazawa, Angjoo},
  year = {2025},
  url = {https://github.com/chungmin99/pyroki}
}""",
    "relaxed-ik-core": """@inproceedings{wang2023rangedik,
  title = {{RangedIK}: An Optimization-based Robot Motion Generation Method for Ranged-Goal Tasks},
  author = {Wang, Yeping and Praveena, Pragathi and Rakita, Daniel and Gleicher, Michael},
  booktitle = {IEEE International Conference on Robotics and Automation (ICRA)},
  year = {2023}
}""",
    "placo": """@misc{placo,
  title = {{PlaCo}: Rhoban Planning and Control},
  author = {{Rhoban}},
  url = {https://github.com/Rhoban/placo}
}""",
    "ikpy": """@misc{ikpy,
  title = {{IKPy}: an inverse kinematics library in Python},
  author = {Manceron, Pierre},
  url = {https://github.com/Phylliade/ikpy}
}""",
}
#: Libraries a method rests on besides its own (sequential-ik, pink and placo use Pinocchio).
ALSO = {"pin-pink": ("pin",), "ikbench": ("pin",)}


def bibtex(libraries: Iterable[str]) -> str:
    """The BibTeX of ikbench and of ``libraries`` (distribution names), each once, in order;
    a library without an entry gets a comment saying so."""
    names = list(dict.fromkeys(["ikbench", *libraries]))
    for name in list(names):
        names += [n for n in ALSO.get(name, ()) if n not in names]
    parts = [BIBTEX.get(name, f"% {name}: no citation known to ikbench; see its project page")
             for name in names]
    return "\n\n".join(parts) + "\n"
