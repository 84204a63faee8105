"""The source digest every manifest records (``source_digest``, part of ``inputs_key``): the package's code without
its comments and docstrings, so that a documentation change leaves stored results current and any change to
the code does not."""

import textwrap

from marinebench.provenance import code_text

BEFORE = textwrap.dedent('''
    """A module."""
    import math

    GAIN = 2.0  # the gain


    def f(x):
        """Twice x.

        Over two lines."""
        # a comment of its own
        return GAIN * x + len("a # not a comment")


    class C:
        "One line."
        y = 1
''')


def test_comments_docstrings_and_blank_lines_do_not_count():
    edited = textwrap.dedent('''
        """Another module docstring, over
        two lines."""
        import math
        GAIN = 2.0   # the gain, reworded
        def f(x):
            """Another docstring."""
            return GAIN * x + len("a # not a comment")   \n
        class C:
            y = 1
    ''')
    assert code_text(edited) == code_text(BEFORE)
    assert "Twice" not in code_text(BEFORE) and "the gain" not in code_text(BEFORE)


def test_every_change_to_the_code_counts():
    for old, new in [
        ("GAIN = 2.0", "GAIN = 2.5"),
        ("not a comment", "not a remark"),  # a '#' in a string is code
        ("    y = 1", "    y = 1\n    z = 'a string assigned'"),
        ("import math", "import math as m"),
        ("    y = 1", "    y = 1\n    print(\n        'an argument on a line of its own'\n    )"),
        ("    y = 1", "    y = 1\n    f'{y}'"),  # an f-string statement evaluates its fields
    ]:
        assert old in BEFORE
        assert code_text(BEFORE.replace(old, new)) != code_text(BEFORE), new
    # a string statement on a line with code is kept with the line, as written
    one_line = "def g(): 'doc'; return 1\n"
    assert code_text(one_line) == one_line.strip()
    assert code_text(one_line.replace("doc", "other")) != code_text(one_line)
